/* SPDX-License-Identifier: MIT */
/* Tests of posix_base's link (pty and TCP) and of its command line. */
#define _XOPEN_SOURCE 700

#include <arpa/inet.h>
#include <errno.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <poll.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "options.h"
#include "posix_link.h"

static int failures;

#define CHECK(cond)                                                                                                    \
    do {                                                                                                               \
        if (!(cond)) {                                                                                                 \
            printf("%s:%d: check failed: %s\n", __FILE__, __LINE__, #cond);                                           \
            failures++;                                                                                                \
        }                                                                                                              \
    } while (0)

/* Wait (at most about 2 s) until the link reports one of `wanted`; returns what it reported. */
static int wait_for(posix_link_t *link, int wanted)
{
    int seen = 0;
    for (int i = 0; i < 200 && (seen & wanted) == 0; i++) {
        int events = posix_link_wait(link, 10);
        CHECK(events >= 0);
        seen |= events > 0 ? events : 0;
    }
    return seen;
}

/* Read from the link until `size` bytes came (or about 2 s passed). */
static size_t read_link(posix_link_t *link, uint8_t *buffer, size_t size)
{
    size_t got = 0;
    for (int i = 0; i < 200 && got < size; i++) {
        (void)posix_link_wait(link, 10);
        long n = posix_link_read(link, buffer + got, size - got);
        CHECK(n >= 0);
        got += n > 0 ? (size_t)n : 0;
    }
    return got;
}

/* Read from a plain descriptor until `size` bytes came, EOF, or about 2 s passed. */
static size_t read_fd(int fd, uint8_t *buffer, size_t size)
{
    size_t got = 0;
    for (int i = 0; i < 200 && got < size; i++) {
        struct pollfd ready = {fd, POLLIN, 0};
        if (poll(&ready, 1, 10) <= 0) {
            continue;
        }
        ssize_t n = read(fd, buffer + got, size - got);
        if (n <= 0) {
            break;
        }
        got += (size_t)n;
    }
    return got;
}

/* Bytes a cooked terminal would mangle: CR, LF, ^C, ^Q/^S, ^D, DEL, and the frame flags. */
static const uint8_t raw_bytes[] = {0x10, 0x0D, 0x0A, 0x03, 0x11, 0x13, 0x04, 0x7F, 0x50, 0xFF, 0x00};

static void test_pty(void)
{
    posix_link_t link;
    char error[160] = "";
    CHECK(posix_link_open_pty(&link, error, sizeof error) == 0);
    CHECK(strncmp(link.name, "/dev/", 5) == 0);
    int peer = open(link.name, O_RDWR | O_NOCTTY);
    CHECK(peer >= 0);
    if (peer < 0) {
        posix_link_close(&link);
        return;
    }

    CHECK(write(peer, raw_bytes, sizeof raw_bytes) == (ssize_t)sizeof raw_bytes);
    uint8_t got[sizeof raw_bytes] = {0};
    CHECK(read_link(&link, got, sizeof got) == sizeof raw_bytes);
    CHECK(memcmp(got, raw_bytes, sizeof raw_bytes) == 0);

    posix_link_write(&link, raw_bytes, sizeof raw_bytes);
    memset(got, 0, sizeof got);
    CHECK(read_fd(peer, got, sizeof got) == sizeof raw_bytes);
    CHECK(memcmp(got, raw_bytes, sizeof raw_bytes) == 0);
    CHECK(link.dropped_bytes == 0);

    /* Nobody reads: the pty fills up and the rest is dropped instead of blocking forever. */
    static uint8_t flood[1 << 20];
    posix_link_write(&link, flood, sizeof flood);
    CHECK(link.dropped_bytes > 0 && link.dropped_bytes < sizeof flood);

    (void)close(peer);
    posix_link_close(&link);
    posix_link_close(&link);
    CHECK(link.io_fd == -1 && link.pty_peer_fd == -1);
}

static int connect_to(const char *name)
{
    const char *colon = strrchr(name, ':');
    struct sockaddr_in address;
    memset(&address, 0, sizeof address);
    address.sin_family = AF_INET;
    address.sin_port = htons((uint16_t)atoi(colon + 1));
    address.sin_addr.s_addr = htonl(INADDR_LOOPBACK);
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    if (fd >= 0 && connect(fd, (struct sockaddr *)&address, sizeof address) != 0) {
        (void)close(fd);
        return -1;
    }
    return fd;
}

static void test_tcp(void)
{
    posix_link_t link;
    char error[160] = "";
    CHECK(posix_link_listen(&link, "127.0.0.1", 0, error, sizeof error) == 0);
    CHECK(strncmp(link.name, "127.0.0.1:", 10) == 0 && atoi(link.name + 10) > 0);

    /* No client yet: writes go nowhere, as on an unplugged cable. */
    posix_link_write(&link, raw_bytes, 3);
    CHECK(link.dropped_bytes == 3);

    int first = connect_to(link.name);
    CHECK(first >= 0);
    CHECK(wait_for(&link, POSIX_LINK_CONNECTED) & POSIX_LINK_CONNECTED);
    CHECK(link.connections == 1);
    CHECK(write(first, "ab", 2) == 2);
    uint8_t got[16] = {0};
    CHECK(read_link(&link, got, 2) == 2 && memcmp(got, "ab", 2) == 0);
    posix_link_write(&link, raw_bytes, sizeof raw_bytes);
    CHECK(read_fd(first, got, sizeof raw_bytes) == sizeof raw_bytes && memcmp(got, raw_bytes, sizeof raw_bytes) == 0);

    /* A second connection replaces the first, which is closed. */
    int second = connect_to(link.name);
    CHECK(second >= 0);
    CHECK(wait_for(&link, POSIX_LINK_CONNECTED) & POSIX_LINK_CONNECTED);
    CHECK(link.connections == 2);
    CHECK(read_fd(first, got, sizeof got) == 0);
    CHECK(write(second, "cd", 2) == 2);
    CHECK(read_link(&link, got, 2) == 2 && memcmp(got, "cd", 2) == 0);
    posix_link_write(&link, (const uint8_t *)"ef", 2);
    CHECK(read_fd(second, got, 2) == 2 && memcmp(got, "ef", 2) == 0);

    /* The peer hangs up: the link closes the connection and keeps listening. */
    (void)close(second);
    CHECK(wait_for(&link, POSIX_LINK_READABLE) & POSIX_LINK_READABLE);
    CHECK(posix_link_read(&link, got, sizeof got) == 0);
    CHECK(link.io_fd == -1 && link.listen_fd >= 0);
    int third = connect_to(link.name);
    CHECK(third >= 0);
    CHECK(wait_for(&link, POSIX_LINK_CONNECTED) & POSIX_LINK_CONNECTED);

    /* The port is taken now: a second listener fails with a message naming it. */
    posix_link_t other;
    CHECK(posix_link_listen(&other, "127.0.0.1", (uint16_t)atoi(link.name + 10), error, sizeof error) == -1);
    CHECK(strstr(error, "cannot listen on 127.0.0.1:") != NULL);
    CHECK(posix_link_listen(&other, "no.such.host.invalid", 0, error, sizeof error) == -1);
    CHECK(strstr(error, "no.such.host.invalid") != NULL);

    (void)close(first);
    (void)close(third);
    posix_link_close(&link);
}

static int parse_args(posix_base_options_t *options, char *error, size_t error_size, const char *const *args)
{
    char *argv[16] = {"posix_base"};
    int argc = 1;
    while (args[argc - 1] != NULL && argc < 16) {
        argv[argc] = (char *)(uintptr_t)args[argc - 1];
        argc++;
    }
    return posix_base_parse_options(argc, argv, options, error, error_size);
}

static void test_options(void)
{
    posix_base_options_t options;
    char error[160];

    const char *const pty[] = {"--pty", NULL};
    CHECK(parse_args(&options, error, sizeof error, pty) == 0);
    CHECK(options.use_pty && options.listen_host[0] == '\0');
    CHECK(options.profile == PROFILE_REFERENCE && options.watchdog_ms == 1000 && options.time_scale_percent == 100);
    CHECK(options.battery_percent == 80 && options.frame_timeout_ms == 100);

    const char *const full[] = {"--listen",      "127.0.0.1:5555", "--profile", "sdk2020", "--watchdog-ms", "0",
                                "--time-scale", "2.5",            "--battery", "15",      "--verbose",
                                "--frame-timeout-ms", "20", NULL};
    CHECK(parse_args(&options, error, sizeof error, full) == 0);
    CHECK(!options.use_pty && strcmp(options.listen_host, "127.0.0.1") == 0 && options.listen_port == 5555);
    CHECK(options.profile == PROFILE_SDK2020 && options.watchdog_ms == 0 && options.time_scale_percent == 250);
    CHECK(options.battery_percent == 15 && options.verbose && options.frame_timeout_ms == 20);

    const char *const ipv6[] = {"--listen", "[::1]:0", NULL};
    CHECK(parse_args(&options, error, sizeof error, ipv6) == 0);
    CHECK(strcmp(options.listen_host, "::1") == 0 && options.listen_port == 0);

    const char *const help[] = {"--help", NULL};
    CHECK(parse_args(&options, error, sizeof error, help) == 0 && options.show_help);

    /* Every bad command line is refused with a message naming what is wrong. */
    const struct {
        const char *args[4];
        const char *message;
    } bad[] = {
        {{NULL}, "choose one link"},
        {{"--pty", "--listen", "127.0.0.1:1", NULL}, "choose one link"},
        {{"--listen", NULL}, "missing value after: --listen"},
        {{"--listen", "127.0.0.1", NULL}, "--listen wants HOST:PORT"},
        {{"--listen", "127.0.0.1:65536", NULL}, "65536"},
        {{"--listen", ":80", NULL}, "--listen wants HOST:PORT"},
        {{"--listen", "h:-1", NULL}, "h:-1"},
        {{"--pty", "--profile", "fancy", NULL}, "--profile wants reference or sdk2020, got: fancy"},
        {{"--pty", "--watchdog-ms", "1e3", NULL}, "--watchdog-ms"},
        {{"--pty", "--frame-timeout-ms", "60001", NULL}, "--frame-timeout-ms wants 0 to 60000"},
        {{"--pty", "--time-scale", "0", NULL}, "--time-scale"},
        {{"--pty", "--time-scale", "nan", NULL}, "--time-scale"},
        {{"--pty", "--battery", "0", NULL}, "--battery"},
        {{"--pty", "--frobnicate", NULL}, "unknown argument: --frobnicate"},
    };
    for (size_t i = 0; i < sizeof bad / sizeof bad[0]; i++) {
        error[0] = '\0';
        int result = parse_args(&options, error, sizeof error, bad[i].args);
        if (result != -1 || strstr(error, bad[i].message) == NULL) {
            printf("bad command line %zu: result %d, message \"%s\", expected \"%s\"\n", i, result, error,
                   bad[i].message);
            failures++;
        }
    }
}

int main(void)
{
    test_pty();
    test_tcp();
    test_options();
    if (failures != 0) {
        printf("test_posix_link: %d check(s) failed\n", failures);
        return 1;
    }
    printf("test_posix_link: all checks passed\n");
    return 0;
}
