/* SPDX-License-Identifier: MIT */
/* The ctrlbus base firmware for mps2-an385: the simulated base (the same sources as posix_base)
 * served on UART0 by the ctrlbus base stack.
 *
 * The UART0 RX interrupt hands each byte to the stack's ring (base_glue_feed is ISR-safe); the
 * main loop polls the stack with the SysTick millisecond clock and sleeps until the next
 * interrupt. Answers are written straight to the UART: no transmit buffer. */
#include <stdint.h>

#include "base_glue.h"
#include "board.h"

#define QEMU_HARDWARE_VERSION 2u /* posix_base says 1 */
/* On real hardware bytes arrive at wire pace and the stack's 10 ms default is right. Under QEMU
 * the UART is fed by the host's scheduler, and a host stall shows as a gap in the guest's clock
 * (its timer follows host time): gaps of up to ~90 ms inside a frame on a loaded host (measured
 * under stress-ng --cpu 2), so 500 ms, five times a host program's 100 ms (docs/protocol.md §7.6). */
#define QEMU_FRAME_TIMEOUT_MS 500u

static base_glue_t glue;

static void feed_byte(void *context, uint8_t byte)
{
    base_glue_feed(context, &byte, 1);
}

static int32_t write_uart(void *context, const uint8_t *data, size_t size)
{
    (void)context;
    board_uart_write(data, size);
    return 0;
}

static void reboot(void *context)
{
    (void)context;
    board_reset();
}

int main(void)
{
    base_glue_options_t options = {0};
    options.hardware_version = QEMU_HARDWARE_VERSION;
    options.frame_timeout_ms = QEMU_FRAME_TIMEOUT_MS;
    options.write = write_uart;
    options.reboot = reboot;
    /* Start the stack before the UART interrupt can deliver a byte into it. */
    if (base_glue_init(&glue, &options, 0) != 0) {
        board_reset();
    }
    board_init(feed_byte, &glue);
    for (;;) {
        base_glue_poll(&glue, board_now_ms());
        board_wait_for_interrupt();
    }
}
