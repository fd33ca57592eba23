/* SPDX-License-Identifier: MIT */
/* The serial link of posix_base; see posix_link.h. */
#define _XOPEN_SOURCE 700 /* posix_openpt, grantpt, unlockpt, ptsname */

#include "posix_link.h"

#include <errno.h>
#include <fcntl.h>
#include <netdb.h>
#include <netinet/in.h>
#include <netinet/tcp.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <termios.h>
#include <unistd.h>

#define WRITE_WAIT_MS 100

static void reset(posix_link_t *link)
{
    memset(link, 0, sizeof *link);
    link->listen_fd = -1;
    link->io_fd = -1;
    link->pty_peer_fd = -1;
}

static int set_nonblocking(int fd)
{
    int flags = fcntl(fd, F_GETFL);
    return flags < 0 ? -1 : fcntl(fd, F_SETFL, flags | O_NONBLOCK);
}

static int fail(posix_link_t *link, char *error, size_t error_size, const char *what)
{
    (void)snprintf(error, error_size, "%s: %s", what, strerror(errno));
    int saved = errno;
    posix_link_close(link);
    errno = saved;
    return -1;
}

int posix_link_open_pty(posix_link_t *link, char *error, size_t error_size)
{
    reset(link);
    link->io_fd = posix_openpt(O_RDWR | O_NOCTTY);
    if (link->io_fd < 0) {
        return fail(link, error, error_size, "cannot create a pty");
    }
    if (grantpt(link->io_fd) != 0 || unlockpt(link->io_fd) != 0) {
        return fail(link, error, error_size, "cannot unlock the pty");
    }
    const char *path = ptsname(link->io_fd);
    if (path == NULL || strlen(path) >= sizeof link->name) {
        return fail(link, error, error_size, "cannot name the pty");
    }
    strcpy(link->name, path);
    /* Holding the slave side open ourselves keeps the master from reading EIO (and losing what
     * we wrote) while no peer has the pty open. */
    link->pty_peer_fd = open(path, O_RDWR | O_NOCTTY);
    if (link->pty_peer_fd < 0) {
        return fail(link, error, error_size, "cannot open the pty");
    }
    struct termios raw;
    if (tcgetattr(link->pty_peer_fd, &raw) != 0) {
        return fail(link, error, error_size, "cannot read the pty settings");
    }
    raw.c_iflag &= ~(tcflag_t)(IGNBRK | BRKINT | PARMRK | ISTRIP | INLCR | IGNCR | ICRNL | IXON | IXOFF);
    raw.c_oflag &= ~(tcflag_t)OPOST;
    raw.c_lflag &= ~(tcflag_t)(ECHO | ECHONL | ICANON | ISIG | IEXTEN);
    raw.c_cflag &= ~(tcflag_t)(CSIZE | PARENB | CSTOPB);
    raw.c_cflag |= CS8 | CLOCAL | CREAD;
    raw.c_cc[VMIN] = 1;
    raw.c_cc[VTIME] = 0;
    (void)cfsetispeed(&raw, B115200);
    (void)cfsetospeed(&raw, B115200);
    if (tcsetattr(link->pty_peer_fd, TCSANOW, &raw) != 0) {
        return fail(link, error, error_size, "cannot set the pty to raw mode");
    }
    if (set_nonblocking(link->io_fd) != 0) {
        return fail(link, error, error_size, "cannot make the pty non-blocking");
    }
    return 0;
}

int posix_link_listen(posix_link_t *link, const char *host, uint16_t port, char *error, size_t error_size)
{
    reset(link);
    char port_text[8];
    (void)snprintf(port_text, sizeof port_text, "%u", (unsigned)port);
    struct addrinfo hints;
    memset(&hints, 0, sizeof hints);
    hints.ai_family = AF_UNSPEC;
    hints.ai_socktype = SOCK_STREAM;
    hints.ai_flags = AI_PASSIVE | AI_NUMERICSERV;
    struct addrinfo *found = NULL;
    int status = getaddrinfo(host, port_text, &hints, &found);
    if (status != 0) {
        (void)snprintf(error, error_size, "cannot listen on %s:%u: %s", host, (unsigned)port, gai_strerror(status));
        return -1;
    }
    int saved_errno = 0;
    for (struct addrinfo *candidate = found; candidate != NULL; candidate = candidate->ai_next) {
        int fd = socket(candidate->ai_family, candidate->ai_socktype, candidate->ai_protocol);
        if (fd < 0) {
            saved_errno = errno;
            continue;
        }
        int yes = 1;
        (void)setsockopt(fd, SOL_SOCKET, SO_REUSEADDR, &yes, sizeof yes);
        if (bind(fd, candidate->ai_addr, candidate->ai_addrlen) == 0 && listen(fd, 1) == 0 &&
            set_nonblocking(fd) == 0) {
            link->listen_fd = fd;
            break;
        }
        saved_errno = errno;
        (void)close(fd);
    }
    freeaddrinfo(found);
    if (link->listen_fd < 0) {
        errno = saved_errno;
        char what[96];
        (void)snprintf(what, sizeof what, "cannot listen on %s:%u", host, (unsigned)port);
        return fail(link, error, error_size, what);
    }
    struct sockaddr_storage bound;
    socklen_t bound_size = sizeof bound;
    char bound_port[8] = "?";
    if (getsockname(link->listen_fd, (struct sockaddr *)&bound, &bound_size) == 0) {
        (void)getnameinfo((struct sockaddr *)&bound, bound_size, NULL, 0, bound_port, sizeof bound_port,
                          NI_NUMERICSERV);
    }
    (void)snprintf(link->name, sizeof link->name, "%s:%s", host, bound_port);
    return 0;
}

static void close_connection(posix_link_t *link)
{
    if (link->listen_fd >= 0 && link->io_fd >= 0) {
        (void)close(link->io_fd);
        link->io_fd = -1;
    }
}

/* Take every pending connection; the last one is the link. */
static int accept_pending(posix_link_t *link)
{
    int events = 0;
    for (;;) {
        int fd = accept(link->listen_fd, NULL, NULL);
        if (fd < 0) {
            return events;
        }
        if (set_nonblocking(fd) != 0) {
            (void)close(fd);
            continue;
        }
        int yes = 1;
        (void)setsockopt(fd, IPPROTO_TCP, TCP_NODELAY, &yes, sizeof yes);
        close_connection(link);
        link->io_fd = fd;
        link->connections++;
        events |= POSIX_LINK_CONNECTED;
    }
}

int posix_link_wait(posix_link_t *link, int timeout_ms)
{
    struct pollfd watched[2];
    nfds_t count = 0;
    if (link->io_fd >= 0) {
        watched[count].fd = link->io_fd;
        watched[count].events = POLLIN;
        watched[count].revents = 0;
        count++;
    }
    if (link->listen_fd >= 0) {
        watched[count].fd = link->listen_fd;
        watched[count].events = POLLIN;
        watched[count].revents = 0;
        count++;
    }
    int ready = poll(watched, count, timeout_ms);
    if (ready < 0) {
        return errno == EINTR ? 0 : -1;
    }
    int events = 0;
    for (nfds_t i = 0; i < count; i++) {
        if (watched[i].fd == link->listen_fd) {
            if (watched[i].revents & POLLIN) {
                events |= accept_pending(link);
            }
        } else if (watched[i].revents & (POLLIN | POLLHUP | POLLERR)) {
            events |= POSIX_LINK_READABLE;
        }
    }
    return events;
}

long posix_link_read(posix_link_t *link, uint8_t *buffer, size_t size)
{
    if (link->io_fd < 0) {
        return 0;
    }
    ssize_t got = read(link->io_fd, buffer, size);
    if (got > 0) {
        return (long)got;
    }
    if (got < 0 && (errno == EAGAIN || errno == EWOULDBLOCK || errno == EINTR)) {
        return 0;
    }
    if (link->listen_fd >= 0) {
        close_connection(link); /* the TCP peer hung up (or the connection failed) */
        return 0;
    }
    if (got < 0 && errno == EIO) {
        return 0; /* pty with no peer: cannot happen while we hold the slave, but harmless */
    }
    return got < 0 ? -1 : 0;
}

void posix_link_write(posix_link_t *link, const uint8_t *data, size_t size)
{
    size_t done = 0;
    while (done < size && link->io_fd >= 0) {
        ssize_t written = link->listen_fd >= 0 ? send(link->io_fd, data + done, size - done, MSG_NOSIGNAL)
                                               : write(link->io_fd, data + done, size - done);
        if (written > 0) {
            done += (size_t)written;
            continue;
        }
        if (written < 0 && errno == EINTR) {
            continue;
        }
        if (written < 0 && (errno == EAGAIN || errno == EWOULDBLOCK)) {
            struct pollfd room = {link->io_fd, POLLOUT, 0};
            if (poll(&room, 1, WRITE_WAIT_MS) > 0) {
                continue;
            }
        } else if (link->listen_fd >= 0) {
            close_connection(link);
        }
        break;
    }
    link->dropped_bytes += size - done;
}

void posix_link_close(posix_link_t *link)
{
    if (link->io_fd >= 0) {
        (void)close(link->io_fd);
    }
    if (link->listen_fd >= 0) {
        (void)close(link->listen_fd);
    }
    if (link->pty_peer_fd >= 0) {
        (void)close(link->pty_peer_fd);
    }
    link->io_fd = -1;
    link->listen_fd = -1;
    link->pty_peer_fd = -1;
}
