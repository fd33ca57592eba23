/* SPDX-License-Identifier: MIT */
/* c/ports/port.h for the Arduino Uno (ATmega328P, 16 MHz, 2 KB RAM), with avr-libc's start-up
 * code and linker script.
 *
 * UART: USART0, 115200 8N1 (U2X, UBRR 16: 117 647 baud, 2.1 % fast, as every Arduino does);
 * the receive-complete interrupt hands each byte to port_uart_received() while port_uart_room()
 * allows (port.h).
 * Clock: Timer1 runs free at F_CPU / 1024 (15.625 kHz); port_millis() turns the counter's advance
 * since its last call into milliseconds, so late or merged interrupts lose no time (it must be
 * called at least every 4.19 s, the counter's wrap). Compare match A fires every 16 counts
 * (1.024 ms), only to wake the main loop from its idle sleep.
 *
 * UNO_QEMU=1 builds the image for `qemu-system-avr -M uno` (QEMU 7.2), whose model differs from
 * the chip in two ways that matter here:
 *   - SLEEP never ends: neither the timer's nor the USART's interrupt wakes the core;
 *   - the USART has no baud rate: the next byte is there as soon as UDR0 is read, so a receive
 *     interrupt drains the host's bytes far faster than an ATmega's main loop digests them and a
 *     small receive ring overflows (on the wire a byte takes 87 us, 1390 cycles), and an
 *     interrupt raised while the main loop has interrupts off (the Timer1 read below) is only
 *     taken when the next one comes.
 * (The chip image, with both, runs under simavr: uno/simavr_uno.c.)
 * So the QEMU image spins instead of sleeping, and receives by polling: port_idle() moves what the
 * USART holds into the stack, at most RX_POLL_BATCH bytes per main-loop turn, and QEMU keeps the
 * rest waiting in the host, as it does while UDR0 is full. (Pacing the receive interrupt instead,
 * disabled by the handler and enabled again by port_idle(), was tried: an interrupt raised while
 * the handler runs is then sometimes taken only when the next byte comes, as above.) */
#include <avr/interrupt.h>
#include <avr/io.h>
#include <avr/sleep.h>
#include <util/atomic.h>

#include "port.h"

#ifndef UNO_QEMU
#define UNO_QEMU 0
#endif

#define UBRR_115200_U2X 16u
#define TICKS_PER_WAKE 16u
/* Timer1 counts per millisecond: 15.625 = 125 / 8. */
#define TICKS_NUM 8u
#define TICKS_DEN 125u
/* Less than the stack's receive ring holds (the minimal base gives it 64 bytes on this board). */
#define RX_POLL_BATCH 32u

/* The free RAM (from the end of .bss to the top of RAM) is painted before main() runs, so that the
 * stack's high-water mark can be read later (a debugger, or QEMU's monitor in the tests: the
 * lowest byte that no longer holds the paint). Section .init3 runs after the stack pointer is set
 * and before anything is pushed; a naked function falls through to the next init section. */
#define STACK_PAINT 0xC5u
extern uint8_t _end; /* the end of .bss, from avr-libc's linker script */
__attribute__((naked, used, section(".init3"))) static void paint_free_ram(void)
{
    for (uint8_t *byte = &_end; byte <= (uint8_t *)RAMEND; byte++) {
        *byte = STACK_PAINT;
    }
}

static uint16_t clock_last_count;
static uint16_t clock_rest; /* count * 8 not yet turned into a millisecond, below 125 */
static uint32_t clock_ms;

void port_init(void)
{
    UBRR0 = UBRR_115200_U2X;
    UCSR0A = (uint8_t)(1u << U2X0);
    UCSR0C = (uint8_t)((1u << UCSZ01) | (1u << UCSZ00)); /* 8N1 */
    TCCR1A = 0;                                          /* normal mode: count 0..0xFFFF */
    TCCR1B = (uint8_t)((1u << CS12) | (1u << CS10));     /* clk / 1024 */
    TCNT1 = 0;
#if UNO_QEMU
    UCSR0B = (uint8_t)((1u << RXEN0) | (1u << TXEN0));
#else
    UCSR0B = (uint8_t)((1u << RXEN0) | (1u << TXEN0) | (1u << RXCIE0));
    OCR1A = TICKS_PER_WAKE;
    TIMSK1 = (uint8_t)(1u << OCIE1A);
    SMCR = 0; /* idle sleep mode (avr-libc's set_sleep_mode() trips -Wconversion) */
    sei();
#endif
}

#if !UNO_QEMU
static volatile uint8_t rx_paused; /* the receive interrupt is masked: the application was full */

ISR(USART_RX_vect)
{
    if (port_uart_room() == 0u) { /* leave the byte in UDR0 until port_idle(), after a poll */
        UCSR0B = (uint8_t)(UCSR0B & (uint8_t)~(1u << RXCIE0));
        rx_paused = 1u;
        return;
    }
    port_uart_received(UDR0);
}

ISR(TIMER1_COMPA_vect)
{
    OCR1A = (uint16_t)(OCR1A + TICKS_PER_WAKE);
}
#endif

/* Timer1's count. QEMU's model does not latch the high byte when the low one is read, so a read
 * across a low-byte wrap can be 256 counts off (16 ms, or 4.2 s once taken as a wrap): read until
 * two reads agree, which a chip (one count per 64 us) always gives at once. */
static uint16_t timer1_count(void)
{
    uint16_t first, second;
    do {
        first = TCNT1;
        second = TCNT1;
    } while ((uint16_t)(second - first) > 1u);
    return second;
}

uint32_t port_millis(void)
{
    uint16_t count;
#if UNO_QEMU
    count = timer1_count(); /* no interrupt is enabled */
#else
    /* A 16-bit register read goes through the TEMP latch, which the interrupt's OCR1A write
     * shares: read with interrupts off. */
    ATOMIC_BLOCK(ATOMIC_RESTORESTATE)
    {
        count = timer1_count();
    }
#endif
    uint16_t advance = (uint16_t)(count - clock_last_count);
#if UNO_QEMU
    /* QEMU restarts the counter from 0 when its overflow callback runs, which is late when the
     * host is busy: the count then steps back by that lateness, and the step must not be taken
     * for a wrap (+4.2 s). This loop reads the clock far more often than every 2.1 s, so an
     * advance over half the range is such a step: count nothing, and go on from the new count. */
    if (advance > 0x8000u) {
        advance = 0;
    }
#endif
    uint32_t scaled = (uint32_t)advance * TICKS_NUM + clock_rest;
    clock_last_count = count;
    clock_ms += scaled / TICKS_DEN;
    clock_rest = (uint16_t)(scaled % TICKS_DEN);
    return clock_ms;
}

void port_uart_write(const uint8_t *data, size_t size)
{
    for (size_t i = 0; i < size; i++) {
        while (!(UCSR0A & (1u << UDRE0))) {
        }
        UDR0 = data[i];
    }
}

void port_idle(void)
{
#if UNO_QEMU
    for (uint8_t taken = 0;
         taken < RX_POLL_BATCH && (UCSR0A & (1u << RXC0)) && port_uart_room() > 0u; taken++) {
        port_uart_received(UDR0);
    }
#else
    if (rx_paused) { /* the main loop has polled: the interrupt takes the waiting byte now */
        rx_paused = 0u;
        UCSR0B = (uint8_t)(UCSR0B | (1u << RXCIE0));
    }
    SMCR = (uint8_t)(1u << SE); /* idle mode; the next interrupt (a byte, the 1 ms wake-up) ends it */
    sleep_cpu();
    SMCR = 0;
#endif
}
