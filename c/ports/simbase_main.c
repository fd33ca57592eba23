/* SPDX-License-Identifier: MIT */
/* The simulated base (c/examples/simbase: a robot in a room, as posix_base and the mps2-an385
 * firmware serve it) on a board of c/ports/, through the same port.h as the minimal base. Built
 * for the 32-bit boards only: its 1 KiB receive ring, 512-byte frame buffer and float simulation
 * do not fit the ATmega328P's 2 KB of RAM. */
#include <stdint.h>

#include "base_glue.h"
#include "port.h"

/* CONNECT_BASE hardware_version: tells the hosts of the simulated base apart (posix_base 1, the
 * mps2-an385 image 2, the other boards 3; the Makefile passes the board's). */
#ifndef SIMBASE_HARDWARE_VERSION
#define SIMBASE_HARDWARE_VERSION 3u
#endif
/* QEMU feeds the UART a byte (or a FIFO) per turn of its event loop, whenever the host runs it,
 * and the guest's clock is the host's: a loaded host leaves gaps of up to ~90 ms inside a frame
 * (measured under stress-ng --cpu 2), so 500 ms, not a host program's 100 ms. */
#define QEMU_FRAME_TIMEOUT_MS 500u

static base_glue_t glue;

static int32_t uart_write(void *context, const uint8_t *data, size_t size)
{
    (void)context;
    port_uart_write(data, size);
    return CTRLBUS_OK;
}

void port_uart_received(uint8_t byte)
{
    base_glue_feed(&glue, &byte, 1);
}

size_t port_uart_room(void)
{
    return base_glue_rx_free(&glue);
}

#ifdef PORT_HAS_RESET
static void reboot(void *context)
{
    (void)context;
    port_reset();
}
#endif

int main(void)
{
    base_glue_options_t options = {0};
    options.hardware_version = SIMBASE_HARDWARE_VERSION;
    options.frame_timeout_ms = QEMU_FRAME_TIMEOUT_MS;
    options.write = uart_write;
#ifdef PORT_HAS_RESET
    options.reboot = reboot;
#endif
    if (base_glue_init(&glue, &options, 0) != 0) {
        return 1;
    }
    port_init();
    for (;;) {
        base_glue_poll(&glue, port_millis());
        port_idle();
    }
}
