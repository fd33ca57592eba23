// SPDX-License-Identifier: MIT
// A stand-in for the Arduino core with only what the ctrlbus example sketches use (Serial,
// millis), so that python/tests/test_release.py can compile and link them from the Arduino zip
// for an ATmega328P (the Uno) with avr-g++, without an Arduino IDE. Not a port: nothing runs.
#ifndef CTRLBUS_ARDUINO_STAND_IN_H
#define CTRLBUS_ARDUINO_STAND_IN_H

#include <stddef.h>
#include <stdint.h>
#include <string.h>

class HardwareSerial {
public:
    void begin(unsigned long baud);
    int available();
    int read();
    size_t write(const uint8_t *data, size_t size);
};

extern HardwareSerial Serial;
unsigned long millis();

#endif
