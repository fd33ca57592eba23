/* SPDX-License-Identifier: MIT */
/* Board support for the mps2-an385 firmware: a 1 ms clock from SysTick and the UART0 driver.
 *
 * The interrupt handlers live in board.c and hand received bytes to one callback that the
 * application registers (board_uart_set_rx_handler); that callback runs in interrupt context. */
#ifndef CTRLBUS_FW_BOARD_H
#define CTRLBUS_FW_BOARD_H

#include <stddef.h>
#include <stdint.h>

/* Called from the UART0 RX interrupt with each received byte. */
typedef void (*board_rx_handler_t)(void *context, uint8_t byte);

/* Start the clock (APB timer 0, free-running), SysTick at 1 kHz (it wakes the main loop) and set
 * UART0 to 115200 8N1 with the RX interrupt enabled. Received bytes go to
 * `rx_handler(context, byte)` in interrupt context. */
void board_init(board_rx_handler_t rx_handler, void *context);

/* Milliseconds since board_init; wraps after 49.7 days. Read from a hardware counter, so no time
 * is lost when interrupts are late. Main loop only, and at least every 171 s (the counter's wrap). */
uint32_t board_now_ms(void);

/* Send bytes on UART0, waiting for the transmit holding register for each one. Main loop only. */
void board_uart_write(const uint8_t *data, size_t size);

/* Sleep until the next interrupt (SysTick wakes the core every millisecond at the latest). */
void board_wait_for_interrupt(void);

/* Reset the chip through the Cortex-M3 AIRCR (used by BASE_CMD REBOOT). Does not return. */
void board_reset(void);

#endif
