/* SPDX-License-Identifier: MIT */
/* What a port is: the six things the minimal base (c/examples/minimal_base/minimal_base.c) needs
 * from a board. Each c/ports/<board>/port.c implements the first four; the application implements
 * port_uart_received(), which the board's UART receive path calls with every byte, and
 * port_uart_room(), which that path asks first.
 *
 * A port owns the hardware: clocks, the UART (115200 8N1), a millisecond clock, interrupts. It
 * knows nothing of the protocol. The application owns the protocol and knows nothing of the
 * hardware. */
#ifndef CTRLBUS_PORT_H
#define CTRLBUS_PORT_H

#include <stddef.h>
#include <stdint.h>

/* Starts the millisecond clock and the UART, with its receive interrupt enabled: from here on
 * port_uart_received() may be called, so start the base stack first. */
void port_init(void);

/* Milliseconds since port_init(), free-running (wraps at 2^32). Main loop only. */
uint32_t port_millis(void);

/* Sends size bytes on the UART, waiting for room as needed. Main loop only. */
void port_uart_write(const uint8_t *data, size_t size);

/* Sleeps until something may need the main loop: the next received byte or the next millisecond
 * tick, whichever comes first. */
void port_idle(void);

/* Optional: resets the chip (does not return). A port that has it defines PORT_HAS_RESET (its
 * Makefile flags); simbase_main.c then serves BASE_CMD REBOOT with it. */
void port_reset(void);

/* Implemented by the application: one received byte, called from the UART receive interrupt (or
 * from port_idle() on a port that polls its UART). */
void port_uart_received(uint8_t byte);

/* Implemented by the application: how many more received bytes it can take now (ISR-safe). The
 * receive path takes a byte from the UART only while this is above 0. At 0 it leaves the bytes in
 * the UART, masks its receive interrupt, and takes them in port_idle(), after the main loop has
 * polled. Why: under QEMU a UART model takes the host's bytes as fast as the guest reads them, not
 * at wire pace, so an emulated CPU that the host starves can meet a burst far larger than its ring;
 * held in the UART, the bytes hold the host back instead of being dropped. On a chip, where bytes
 * come at wire pace, the ring is seldom full; when it is, the UART's FIFO keeps a few more bytes
 * before it overruns. */
size_t port_uart_room(void);

#endif
