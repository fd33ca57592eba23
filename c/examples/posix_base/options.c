/* SPDX-License-Identifier: MIT */
/* Command line of posix_base: hand-written (getopt_long is not POSIX) and strict: every value is
 * checked, and anything unexpected is an error naming the argument. */
#include "options.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static const char usage_text[] =
    "usage: posix_base (--pty | --listen HOST:PORT) [options]\n"
    "\n"
    "A simulated differential-drive robot base speaking the SLAMWARE Control Bus as the slave,\n"
    "built on the ctrlbus C base stack. It serves one serial link:\n"
    "\n"
    "  --pty                  create a pseudo-terminal and print its path (\"pty: /dev/pts/N\")\n"
    "  --listen HOST:PORT     listen on TCP; each accepted connection is the serial link and a\n"
    "                         new connection replaces the old one as a new line (nothing the\n"
    "                         old one half sent carries over). PORT 0 picks a free port.\n"
    "                         Prints \"listen: HOST:PORT\" once listening.\n"
    "\n"
    "options:\n"
    "  --profile NAME         answer sizes: reference (2018 reference base: CONNECT 28 bytes,\n"
    "                         deadreckon 13) or sdk2020 (what the 2020 master SDK reads: CONNECT 39,\n"
    "                         deadreckon 17); default reference\n"
    "  --watchdog-ms MS       stop the wheels when no CTRL_BUS request came for MS ms; 0 turns the\n"
    "                         motor watchdog off; default 1000\n"
    "  --frame-timeout-ms MS  drop a partial frame after MS ms without a byte (0 to 60000; 0 turns\n"
    "                         it off); default 100, for a host behind a USB-serial adapter\n"
    "  --binary-config FILE   serve the bytes of FILE (a blob from `ctrlbus config encode`, at most\n"
    "                         65534 bytes) for GET_BASE_CONF_ADV (0x21); without it 0x21 is\n"
    "                         answered ERROR 0x8000 and the Core falls back to GET_BASE_CONF\n"
    "  --time-scale FACTOR    simulated time per real time (0.01 to 1000); default 1\n"
    "  --battery PERCENT      battery charge at start (1 to 100); default 80\n"
    "  --max-wheel-speed MM_S limit what the Core commands to MM_S mm/s per wheel (1 to 65535),\n"
    "                         scaling both wheels together so that a curve keeps its curvature;\n"
    "                         default 1000, the simulated robot's top speed (wheel track 236 mm);\n"
    "                         0 turns the limit off (each wheel is then clamped on its own)\n"
    "  --verbose              log connections on stderr\n"
    "  --help                 show this text\n"
    "\n"
    "Exit status: 0 after SIGINT or SIGTERM, 2 on a bad command line or when the link cannot be\n"
    "opened.\n";

const char *posix_base_usage(void)
{
    return usage_text;
}

static int fail(char *error, size_t error_size, const char *what, const char *argument)
{
    (void)snprintf(error, error_size, "%s: %s", what, argument);
    return -1;
}

/* A whole decimal number within [min, max]. */
static int parse_unsigned(const char *text, unsigned long min, unsigned long max, unsigned long *value)
{
    if (text[0] < '0' || text[0] > '9') {
        return -1;
    }
    char *end = NULL;
    errno = 0;
    unsigned long parsed = strtoul(text, &end, 10);
    if (errno != 0 || *end != '\0' || parsed < min || parsed > max) {
        return -1;
    }
    *value = parsed;
    return 0;
}

static int parse_listen(const char *text, posix_base_options_t *options)
{
    const char *colon = strrchr(text, ':');
    if (colon == NULL || colon == text) {
        return -1;
    }
    size_t host_length = (size_t)(colon - text);
    /* [::1]:5555 style: drop the brackets. */
    if (text[0] == '[' && host_length >= 2 && colon[-1] == ']') {
        text++;
        host_length -= 2;
    }
    if (host_length == 0 || host_length >= sizeof options->listen_host) {
        return -1;
    }
    unsigned long port = 0;
    if (parse_unsigned(colon + 1, 0, 65535, &port) != 0) {
        return -1;
    }
    memcpy(options->listen_host, text, host_length);
    options->listen_host[host_length] = '\0';
    options->listen_port = (uint16_t)port;
    return 0;
}

static int parse_time_scale(const char *text, uint32_t *percent)
{
    char *end = NULL;
    errno = 0;
    double factor = strtod(text, &end);
    if (errno != 0 || end == text || *end != '\0' || !(factor >= 0.01 && factor <= 1000.0)) {
        return -1;
    }
    *percent = (uint32_t)(factor * 100.0 + 0.5);
    return 0;
}

int posix_base_parse_options(int argc, char **argv, posix_base_options_t *options, char *error, size_t error_size)
{
    posix_base_options_t defaults = {0};
    defaults.profile = PROFILE_REFERENCE;
    defaults.watchdog_ms = POSIX_BASE_DEFAULT_WATCHDOG_MS;
    defaults.frame_timeout_ms = POSIX_BASE_DEFAULT_FRAME_TIMEOUT_MS;
    defaults.time_scale_percent = 100;
    defaults.battery_percent = 80;
    defaults.max_wheel_mm_s = POSIX_BASE_DEFAULT_MAX_WHEEL_MM_S;
    *options = defaults;
    int have_listen = 0;

    for (int i = 1; i < argc; i++) {
        const char *arg = argv[i];
        int takes_value = strcmp(arg, "--listen") == 0 || strcmp(arg, "--profile") == 0 ||
                          strcmp(arg, "--watchdog-ms") == 0 || strcmp(arg, "--time-scale") == 0 ||
                          strcmp(arg, "--frame-timeout-ms") == 0 || strcmp(arg, "--binary-config") == 0 ||
                          strcmp(arg, "--battery") == 0 || strcmp(arg, "--max-wheel-speed") == 0;
        const char *value = NULL;
        if (takes_value) {
            if (i + 1 >= argc) {
                return fail(error, error_size, "missing value after", arg);
            }
            value = argv[++i];
        }
        unsigned long number = 0;
        if (strcmp(arg, "--help") == 0 || strcmp(arg, "-h") == 0) {
            options->show_help = 1;
        } else if (strcmp(arg, "--pty") == 0) {
            options->use_pty = 1;
        } else if (strcmp(arg, "--verbose") == 0) {
            options->verbose = 1;
        } else if (strcmp(arg, "--listen") == 0) {
            if (parse_listen(value, options) != 0) {
                return fail(error, error_size, "--listen wants HOST:PORT with PORT 0-65535, got", value);
            }
            have_listen = 1;
        } else if (strcmp(arg, "--profile") == 0) {
            if (strcmp(value, "reference") == 0) {
                options->profile = PROFILE_REFERENCE;
            } else if (strcmp(value, "sdk2020") == 0) {
                options->profile = PROFILE_SDK2020;
            } else {
                return fail(error, error_size, "--profile wants reference or sdk2020, got", value);
            }
        } else if (strcmp(arg, "--watchdog-ms") == 0) {
            if (parse_unsigned(value, 0, 3600000, &number) != 0) {
                return fail(error, error_size, "--watchdog-ms wants 0 to 3600000, got", value);
            }
            options->watchdog_ms = (uint32_t)number;
        } else if (strcmp(arg, "--frame-timeout-ms") == 0) {
            if (parse_unsigned(value, 0, POSIX_BASE_MAX_FRAME_TIMEOUT_MS, &number) != 0) {
                return fail(error, error_size, "--frame-timeout-ms wants 0 to 60000, got", value);
            }
            options->frame_timeout_ms = (uint32_t)number;
        } else if (strcmp(arg, "--binary-config") == 0) {
            options->binary_config_path = value;
        } else if (strcmp(arg, "--time-scale") == 0) {
            if (parse_time_scale(value, &options->time_scale_percent) != 0) {
                return fail(error, error_size, "--time-scale wants a factor from 0.01 to 1000, got", value);
            }
        } else if (strcmp(arg, "--battery") == 0) {
            if (parse_unsigned(value, 1, 100, &number) != 0) {
                return fail(error, error_size, "--battery wants a percentage from 1 to 100, got", value);
            }
            options->battery_percent = (int32_t)number;
        } else if (strcmp(arg, "--max-wheel-speed") == 0) {
            if (parse_unsigned(value, 0, POSIX_BASE_MAX_WHEEL_LIMIT_MM_S, &number) != 0) {
                return fail(error, error_size, "--max-wheel-speed wants mm/s from 0 to 65535, got", value);
            }
            options->max_wheel_mm_s = number == 0u ? -1 : (int32_t)number;
        } else {
            return fail(error, error_size, "unknown argument", arg);
        }
    }
    if (options->show_help) {
        return 0;
    }
    if (options->use_pty == have_listen) {
        return fail(error, error_size, "choose one link", "--pty or --listen HOST:PORT");
    }
    return 0;
}
