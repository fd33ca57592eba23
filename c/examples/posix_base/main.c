/* SPDX-License-Identifier: MIT */
/* posix_base: the simulated base served over a pty or TCP by the ctrlbus base stack.
 *
 * This file is the host's I/O only: the command line, the link, a monotonic clock and the main
 * loop. Everything about the protocol and the simulated robot is behind base_glue.h, which the
 * QEMU firmware uses too. */
#define _XOPEN_SOURCE 700 /* sigaction, clock_gettime */

#include <errno.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

#include "base_glue.h"
#include "options.h"
#include "posix_link.h"

/* The longest the loop sleeps: bounds how late the watchdog and the simulation run. */
#define LOOP_PERIOD_MS 5
#define POSIX_HARDWARE_VERSION 1u /* the QEMU firmware says 2 */

static volatile sig_atomic_t stop_requested;

static void on_stop_signal(int signal_number)
{
    (void)signal_number;
    stop_requested = 1;
}

static int install_signal_handlers(void)
{
    struct sigaction action;
    memset(&action, 0, sizeof action);
    action.sa_handler = on_stop_signal;
    (void)sigemptyset(&action.sa_mask);
    struct sigaction ignore;
    memset(&ignore, 0, sizeof ignore);
    ignore.sa_handler = SIG_IGN;
    (void)sigemptyset(&ignore.sa_mask);
    return sigaction(SIGINT, &action, NULL) == 0 && sigaction(SIGTERM, &action, NULL) == 0 &&
                   sigaction(SIGPIPE, &ignore, NULL) == 0
               ? 0
               : -1;
}

static uint32_t monotonic_ms(void)
{
    struct timespec now;
    (void)clock_gettime(CLOCK_MONOTONIC, &now);
    /* Wraps after 49.7 days; the stack compares times by difference, so that is fine. */
    return (uint32_t)((uint64_t)now.tv_sec * 1000u + (uint64_t)now.tv_nsec / 1000000u);
}

/* Answers are streamed to us in small pieces; gather them so that one answer leaves in one
 * write (one TCP segment) rather than one per field. */
typedef struct {
    posix_link_t link;
    uint8_t pending[4096];
    size_t pending_size;
} output_t;

static void flush_output(output_t *output)
{
    if (output->pending_size > 0) {
        posix_link_write(&output->link, output->pending, output->pending_size);
        output->pending_size = 0;
    }
}

static int32_t write_to_link(void *context, const uint8_t *data, size_t size)
{
    output_t *output = context;
    while (size > 0) {
        if (output->pending_size == sizeof output->pending) {
            flush_output(output);
        }
        size_t room = sizeof output->pending - output->pending_size;
        size_t chunk = size < room ? size : room;
        memcpy(output->pending + output->pending_size, data, chunk);
        output->pending_size += chunk;
        data += chunk;
        size -= chunk;
    }
    return 0;
}

static int fail(const char *message)
{
    (void)fprintf(stderr, "posix_base: error: %s\n", message);
    return 2;
}

/* The largest blob the stack serves (ctrlbus_base_config_t.binary_config_size). */
#define BINARY_CONFIG_MAX 65534u

/* Reads the --binary-config file into blob[BINARY_CONFIG_MAX]. Returns its size, or -1 with a
 * one-line reason in error. */
static long read_binary_config(const char *path, uint8_t *blob, char *error, size_t error_size)
{
    FILE *file = fopen(path, "rb");
    if (file == NULL) {
        (void)snprintf(error, error_size, "cannot read --binary-config %s: %s", path, strerror(errno));
        return -1;
    }
    size_t size = fread(blob, 1, BINARY_CONFIG_MAX, file);
    int failed = ferror(file);
    int extra = fgetc(file) != EOF;
    (void)fclose(file);
    if (failed) {
        (void)snprintf(error, error_size, "cannot read --binary-config %s", path);
        return -1;
    }
    if (extra || size == 0) {
        (void)snprintf(error, error_size, "--binary-config %s: a blob holds 1 to %u bytes, this file %s", path,
                       BINARY_CONFIG_MAX, size == 0 ? "is empty" : "is larger");
        return -1;
    }
    return (long)size;
}

int main(int argc, char **argv)
{
    posix_base_options_t options;
    char error[256];
    if (posix_base_parse_options(argc, argv, &options, error, sizeof error) != 0) {
        (void)fprintf(stderr, "posix_base: error: %s (see --help)\n", error);
        return 2;
    }
    if (options.show_help) {
        (void)fputs(posix_base_usage(), stdout);
        return 0;
    }
    if (install_signal_handlers() != 0) {
        return fail("cannot install signal handlers");
    }

    static uint8_t binary_config[BINARY_CONFIG_MAX];
    long binary_config_size = 0;
    if (options.binary_config_path != NULL &&
        (binary_config_size = read_binary_config(options.binary_config_path, binary_config, error, sizeof error)) < 0) {
        return fail(error);
    }

    static output_t output;
    int opened = options.use_pty
                     ? posix_link_open_pty(&output.link, error, sizeof error)
                     : posix_link_listen(&output.link, options.listen_host, options.listen_port, error, sizeof error);
    if (opened != 0) {
        return fail(error);
    }

    static base_glue_t glue;
    base_glue_options_t glue_options;
    memset(&glue_options, 0, sizeof glue_options);
    glue_options.watchdog_ms = options.watchdog_ms;
    glue_options.watchdog_off = options.watchdog_ms == 0;
    glue_options.frame_timeout_ms = options.frame_timeout_ms == 0 ? CTRLBUS_BASE_TIMEOUT_OFF
                                                                  : (uint16_t)options.frame_timeout_ms;
    glue_options.hardware_version = POSIX_HARDWARE_VERSION;
    glue_options.time_scale_percent = options.time_scale_percent;
    glue_options.sdk2020_sizes = options.profile == PROFILE_SDK2020;
    if (binary_config_size > 0) {
        glue_options.binary_config = binary_config;
        glue_options.binary_config_size = (uint16_t)binary_config_size;
    }
    glue_options.sim.battery_start_percent = options.battery_percent;
    glue_options.sim.max_wheel_speed_mm_s = POSIX_BASE_DEFAULT_MAX_WHEEL_MM_S;
    glue_options.max_wheel_mm_s = options.max_wheel_mm_s;
    glue_options.write = write_to_link;
    glue_options.write_context = &output;
    if (base_glue_init(&glue, &glue_options, monotonic_ms()) != 0) {
        posix_link_close(&output.link);
        return fail("cannot start the base stack");
    }

    /* One line on stdout says where to connect; scripts wait for it. */
    (void)printf("%s: %s\n", options.use_pty ? "pty" : "listen", output.link.name);
    (void)fflush(stdout);

    int status = 0;
    while (!stop_requested) {
        int events = posix_link_wait(&output.link, LOOP_PERIOD_MS);
        if (events < 0) {
            (void)snprintf(error, sizeof error, "waiting on %s failed: %s", output.link.name, strerror(errno));
            status = fail(error);
            break;
        }
        if (events & POSIX_LINK_CONNECTED) {
            /* A new connection is a new line: nothing of the old one's half frame carries over. */
            base_glue_new_line(&glue);
            if (options.verbose) {
                (void)fprintf(stderr, "posix_base: connection %llu is now the link\n",
                              (unsigned long long)output.link.connections);
            }
        }
        uint8_t received[BASE_GLUE_RX_RING_SIZE / 2u]; /* the ring holds one byte less than its size */
        long got = 0;
        /* Poll after every chunk, so a burst longer than the stack's receive ring is parsed as it
         * comes instead of overflowing the ring. */
        while ((got = posix_link_read(&output.link, received, sizeof received)) > 0) {
            base_glue_feed(&glue, received, (size_t)got);
            base_glue_poll(&glue, monotonic_ms());
        }
        if (got < 0) {
            (void)snprintf(error, sizeof error, "reading %s failed: %s", output.link.name, strerror(errno));
            status = fail(error);
            break;
        }
        base_glue_poll(&glue, monotonic_ms());
        flush_output(&output);
    }
    if (options.verbose && output.link.dropped_bytes > 0) {
        (void)fprintf(stderr, "posix_base: %llu answer bytes dropped (nobody was reading)\n",
                      (unsigned long long)output.link.dropped_bytes);
    }
    posix_link_close(&output.link);
    return status;
}
