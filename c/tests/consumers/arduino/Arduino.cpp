// SPDX-License-Identifier: MIT
// The stand-in's definitions (see Arduino.h) and the core's main(): setup() once, then loop().
// The volatile register keeps the linker from discarding what the sketch reads and writes.
#include "Arduino.h"

static volatile uint8_t uart_data;

HardwareSerial Serial;

void HardwareSerial::begin(unsigned long baud) { uart_data = (uint8_t)baud; }
int HardwareSerial::available() { return uart_data; }
int HardwareSerial::read() { return uart_data; }
size_t HardwareSerial::write(const uint8_t *data, size_t size)
{
    for (size_t i = 0; i < size; i++) {
        uart_data = data[i];
    }
    return size;
}

unsigned long millis() { return uart_data; }

void setup();
void loop();

int main()
{
    setup();
    for (;;) {
        loop();
    }
}
