/* SPDX-License-Identifier: MIT */
/* What a port is: the five things the minimal base (c/examples/minimal_base/minimal_base.c) needs
 * from a board. Each c/ports/<board>/port.c implements the first four; the application implements
 * port_uart_received(), which the board's UART receive path calls with every byte.
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

#endif
