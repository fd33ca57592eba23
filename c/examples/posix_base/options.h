/* SPDX-License-Identifier: MIT */
/* Command line of posix_base. */
#ifndef CTRLBUS_POSIX_BASE_OPTIONS_H
#define CTRLBUS_POSIX_BASE_OPTIONS_H

#include <stddef.h>
#include <stdint.h>

typedef enum {
    PROFILE_REFERENCE, /* answer sizes of the vendor's 2018 reference base (CONNECT 28, 0x41 13) */
    PROFILE_SDK2020    /* answer sizes the vendor's 2020 master SDK reads (CONNECT 39, 0x41 17) */
} posix_base_profile_t;

typedef struct {
    int show_help;
    int use_pty;
    char listen_host[64]; /* empty unless --listen */
    uint16_t listen_port; /* 0: let the system pick one (the chosen port is printed) */
    posix_base_profile_t profile;
    uint32_t watchdog_ms;        /* 0: motor watchdog off */
    uint32_t frame_timeout_ms;   /* inter-byte timeout; 0: off */
    uint32_t time_scale_percent; /* simulated time per real time; 100 = real time */
    int32_t battery_percent;     /* battery at start, 1..100 */
    int32_t max_wheel_mm_s;      /* the stack's wheel-speed limit; negative: none */
    const char *binary_config_path; /* NULL unless --binary-config: the blob served for 0x21 */
    int verbose;
} posix_base_options_t;

#define POSIX_BASE_DEFAULT_WATCHDOG_MS 1000u
/* A host reads its link in bursts (scheduling, USB-serial latency timers): the inter-byte timeout
 * of a host program (docs/protocol.md §7.6), not an MCU's 10 ms. */
#define POSIX_BASE_DEFAULT_FRAME_TIMEOUT_MS 100u
#define POSIX_BASE_MAX_FRAME_TIMEOUT_MS 60000u
/* The simulated robot's top wheel speed (simbase's default), the default limit. */
#define POSIX_BASE_DEFAULT_MAX_WHEEL_MM_S 1000
#define POSIX_BASE_MAX_WHEEL_LIMIT_MM_S 65535u

/* Parse argv into *options (defaults first). Returns 0 on success; on a bad command line returns
 * -1 with a one-line description in error[error_size] (no trailing newline). */
int posix_base_parse_options(int argc, char **argv, posix_base_options_t *options, char *error, size_t error_size);

/* The --help text. */
const char *posix_base_usage(void);

#endif
