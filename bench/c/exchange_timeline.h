/* SPDX-License-Identifier: MIT */
/* The firmware's view of a Core<->base exchange, shared by the exchange harnesses (ours and the
 * floor), so that both are driven by exactly the same loop.
 *
 * The line runs at 115200 baud: a byte slot is ~87 us, so a new millisecond every 11 slots. Each
 * exchange is the request's slots (one byte handed to the receive "interrupt" per slot) followed
 * by the answer's slots (the line carries the answer; nothing is received). After every 11th slot
 * the clock advances 1 ms and the main loop polls once. So a SET_V_AND_GET_DEADRECKON exchange
 * (17 + 18 slots) sees about 3.2 polls, one of which finds the whole request and writes the
 * answer, and the exchanges follow each other as fast as the line allows (~330 a second).
 *
 * The includer defines the two entry points a firmware has:
 *   static void isr_byte(void *base, uint8_t byte);       the receive interrupt, one byte
 *   static void main_poll(void *base, uint32_t now_ms);   the main loop's call, once per ms
 * and calls run_timeline(). In baseline mode both are replaced by stores the compiler cannot drop,
 * so (Ir(mode) - Ir(baseline)) / exchanges is the firmware's own work per exchange. */
#ifndef CTRLBUS_BENCH_EXCHANGE_TIMELINE_H
#define CTRLBUS_BENCH_EXCHANGE_TIMELINE_H

#include <stddef.h>
#include <stdint.h>

#define SLOTS_PER_MS 11u

/* Size of the frame starting at data[0], from its header; 0 if it is not a whole frame. */
static size_t timeline_frame_size(const unsigned char *data, size_t left)
{
    size_t size = 0;
    if (left >= 2 && data[0] == 0x10u) {
        size = (size_t)data[1] + 3u;
    } else if (left >= 3 && data[0] == 0x50u) {
        size = ((size_t)data[1] | (size_t)data[2] << 8) + 4u;
    }
    return size <= left ? size : 0u;
}

/* Functions of their own in both harnesses, as in a firmware: the hardware enters the interrupt
 * handler for each byte, and the main loop calls its poll; neither is inlined into this loop
 * (which would keep the ring's state in registers from one byte to the next, as no interrupt
 * handler can). */
#if defined(__GNUC__)
#define TIMELINE_ENTRY __attribute__((noinline))
#else
#define TIMELINE_ENTRY
#endif
static TIMELINE_ENTRY void isr_byte(void *base, uint8_t byte);
static TIMELINE_ENTRY void main_poll(void *base, uint32_t now_ms);

/* Runs every request of data[0..size) through the timeline, each followed by answer_slots idle
 * slots. Returns the number of exchanges, or -1 when the file is not whole frames. */
static long run_timeline(void *base, const unsigned char *data, size_t size, size_t answer_slots,
                         int baseline)
{
    volatile unsigned char sink = 0;
    volatile uint32_t clock_sink = 0;
    uint32_t now_ms = 0;
    unsigned slot = 0;
    long exchanges = 0;
    for (size_t pos = 0; pos < size;) {
        size_t len = timeline_frame_size(data + pos, size - pos);
        if (len == 0) {
            return -1;
        }
        for (size_t i = 0; i < len + answer_slots; i++) {
            if (i < len) {
                if (baseline) {
                    sink = data[pos + i];
                } else {
                    isr_byte(base, data[pos + i]);
                }
            }
            if (++slot == SLOTS_PER_MS) {
                slot = 0;
                now_ms++;
                if (baseline) {
                    clock_sink = now_ms;
                } else {
                    main_poll(base, now_ms);
                }
            }
        }
        pos += len;
        exchanges++;
    }
    (void)sink;
    (void)clock_sink;
    return exchanges;
}

#endif
