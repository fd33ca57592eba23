/* SPDX-License-Identifier: MIT */
/* The serial link of posix_base: a pseudo-terminal, or a TCP listener whose latest accepted
 * connection is the link (a new connection replaces the old one, like replugging a cable).
 *
 * Writes never block for long, as a UART's never do: bytes for a link that nobody reads (no
 * TCP client, a pty whose buffer is full) are dropped and counted. */
#ifndef CTRLBUS_POSIX_LINK_H
#define CTRLBUS_POSIX_LINK_H

#include <stddef.h>
#include <stdint.h>

typedef struct {
    int listen_fd;    /* TCP listener, -1 for a pty */
    int io_fd;        /* pty master or the current TCP connection, -1 when none */
    int pty_peer_fd;  /* our own handle on the pty's slave side, -1 for TCP */
    char name[128];   /* pty path, or HOST:PORT actually bound */
    uint64_t connections;
    uint64_t dropped_bytes;
} posix_link_t;

/* What posix_link_wait saw. */
#define POSIX_LINK_READABLE 0x1
#define POSIX_LINK_CONNECTED 0x2 /* a new TCP connection became the link */

/* Create a pty in raw mode (no echo, no line editing, no CR/LF translation). Returns 0, or -1
 * with a one-line message in error[error_size]. */
int posix_link_open_pty(posix_link_t *link, char *error, size_t error_size);

/* Listen on host:port (port 0 picks a free one; link->name tells which). Returns 0, or -1 with a
 * one-line message. */
int posix_link_listen(posix_link_t *link, const char *host, uint16_t port, char *error, size_t error_size);

/* Wait up to timeout_ms for input or a connection and accept new connections. Returns a set of
 * POSIX_LINK_* bits (0 on timeout or a signal), or -1 with errno set on a failure. */
int posix_link_wait(posix_link_t *link, int timeout_ms);

/* Read what is available, without waiting. Returns the number of bytes (0 if none), or -1 with
 * errno set on a failure of a pty. A TCP connection whose peer hung up is closed (io_fd becomes
 * -1) and reads 0; the listener waits for the next one. */
long posix_link_read(posix_link_t *link, uint8_t *buffer, size_t size);

/* Send all of data, waiting at most 100 ms for room; what does not fit then is dropped and
 * counted in dropped_bytes. */
void posix_link_write(posix_link_t *link, const uint8_t *data, size_t size);

/* Close everything; safe to call twice. */
void posix_link_close(posix_link_t *link);

#endif
