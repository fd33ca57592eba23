/* SPDX-License-Identifier: MIT */
/* c/ports/port.h on a POSIX host: the "UART" is a pseudo-terminal (posix_base's link code), the
 * clock CLOCK_MONOTONIC, and "waiting for an interrupt" is waiting for input with a timeout.
 *
 * port_init() prints "pty: /dev/pts/N" on stdout; connect any ctrlbus tool there:
 *     ./minimal_base &    ctrlbus check --port /dev/pts/N
 * SIGINT and SIGTERM end the program (the default action), which closes the pty. */
#define _XOPEN_SOURCE 700 /* clock_gettime */

#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "port.h"
#include "posix_link.h"

/* The longest port_idle() waits: the clock's tick, as a timer interrupt would wake an MCU. */
#define IDLE_MS 1
/* Bytes taken per port_idle(): the main loop polls between two chunks, so the stack's receive
 * ring only ever holds one chunk (it must be larger than this). */
#define READ_CHUNK 64u

static posix_link_t pty_link;
static uint32_t start_ms;

static uint32_t monotonic_ms(void)
{
    struct timespec now;
    (void)clock_gettime(CLOCK_MONOTONIC, &now);
    return (uint32_t)((uint64_t)now.tv_sec * 1000u + (uint64_t)now.tv_nsec / 1000000u);
}

void port_init(void)
{
    char error[256];
    if (posix_link_open_pty(&pty_link, error, sizeof error) != 0) {
        (void)fprintf(stderr, "minimal_base: error: %s\n", error);
        exit(2);
    }
    start_ms = monotonic_ms();
    (void)printf("pty: %s\n", pty_link.name);
    (void)fflush(stdout);
}

uint32_t port_millis(void)
{
    return monotonic_ms() - start_ms;
}

void port_uart_write(const uint8_t *data, size_t size)
{
    posix_link_write(&pty_link, data, size);
}

void port_idle(void)
{
    uint8_t received[READ_CHUNK];
    if (posix_link_wait(&pty_link, IDLE_MS) < 0) {
        return; /* a signal; the next call waits again */
    }
    /* No more than the ring takes: the rest waits in the pty for the next turn. */
    size_t room = port_uart_room();
    if (room == 0u) {
        return; /* (a read of 0 bytes would look like a hang-up) */
    }
    long got = posix_link_read(&pty_link, received, room < sizeof received ? room : sizeof received);
    for (long i = 0; i < got; i++) {
        port_uart_received(received[i]);
    }
}
