/* SPDX-License-Identifier: MIT */
/* base_glue: the simulated base (simbase) served by the ctrlbus base stack (ctrlbus/base.h).
 *
 * One piece of code for both hosts of the simulated base: posix_base (c/examples/posix_base, a
 * pty or TCP link) and the boards of c/ports (simbase_main.c, a UART). They only move bytes and time:
 *
 *     base_glue_init(&glue, &options, now_ms);
 *     on received bytes (main loop or UART interrupt):   base_glue_feed(&glue, data, size);
 *     in the main loop, at least every few ms:            base_glue_poll(&glue, now_ms);
 *
 * and answers leave through options.write. Everything else lives here: the stack instance and its
 * receive ring, the simulation and its clock, and the handlers that answer each request from the
 * simulation (simbase_answers.h) or apply it to the simulation.
 *
 * The simulation runs on its own clock (time_scale_percent of real time); the stack's watchdog and
 * frame timeout run on real time. By default the stack limits commands to the simulated robot's
 * top wheel speed (see max_wheel_mm_s below). Health: the battery's condition is re-evaluated at
 * every poll (the reference does it every 100 ms) and registered as the reference does
 * (0x01020100 below 30 %, 0x02020100 below 10 %), next to the stack's own motor-watchdog warning.
 */
#ifndef CTRLBUS_EXAMPLES_BASE_GLUE_H
#define CTRLBUS_EXAMPLES_BASE_GLUE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ctrlbus/base.h"
#include "ctrlbus/frame.h"
#include "simbase.h"
#include "simbase_answers.h"

/* Receive ring and frame buffer: the reference base's 512-byte request limit. */
#define BASE_GLUE_RX_RING_SIZE 1024u
#define BASE_GLUE_FRAME_BUFFER_SIZE 512u

typedef struct {
    uint32_t watchdog_ms;         /* motor watchdog period; 0: the stack's default (1000 ms) */
    uint16_t frame_timeout_ms;    /* inter-byte timeout; 0: the stack's default (10 ms, an MCU's) */
    bool watchdog_off;            /* no motor watchdog at all */
    uint32_t time_scale_percent;  /* simulated time per real time; 0 means 100 (real time) */
    bool sdk2020_sizes;           /* CONNECT 39 and deadreckon 17 bytes instead of 28 and 13 */
    const uint8_t *binary_config; /* GET_BASE_CONF_ADV blob (caller-owned); NULL: ERROR 0x8000 */
    uint16_t binary_config_size;
    uint16_t hardware_version;    /* CONNECT_BASE hardware_version: tells the hosts apart */
    simbase_config_t sim;         /* zero fields: simbase defaults */
    /* The stack's velocity limit (ctrlbus_base_limits_t.max_wheel_mm_s, with the simulated
     * robot's wheel track, so that a limited command keeps its curvature). 0: the simulated
     * robot's top wheel speed (sim.max_wheel_speed_mm_s); negative: no limit in the stack (each
     * wheel is then clamped on its own by the simulation, which straightens a curve). */
    int32_t max_wheel_mm_s;
    ctrlbus_write_fn write;       /* where answers go (required) */
    void *write_context;
    void (*reboot)(void *context); /* BASE_CMD REBOOT after its OK answer; NULL: unsupported */
    void *reboot_context;
} base_glue_options_t;

#define BASE_GLUE_HEALTH_ENTRIES 4u

/* Caller-owned (static in both hosts); fields are private to base_glue.c. */
typedef struct {
    ctrlbus_base_t base;
    ctrlbus_base_config_t config; /* the stack keeps a pointer to it */
    uint8_t rx_ring[BASE_GLUE_RX_RING_SIZE];
    uint8_t frame_buffer[BASE_GLUE_FRAME_BUFFER_SIZE];
    ctrlbus_base_health_entry_t health[BASE_GLUE_HEALTH_ENTRIES];
    simbase_t sim;
    simbase_identity_t identity;
    ctrlbus_get_base_conf_answer_t base_conf; /* GET_BASE_CONF, streamed from here */
    base_glue_options_t options;
    uint32_t last_poll_ms;      /* the simulation has been stepped up to here */
    uint32_t sim_remainder;     /* scaled time not yet stepped, in 1/100 ms */
    uint8_t probes[SIMBASE_PROBE_COUNT]; /* GET_CHARGER_DATA answer storage */
} base_glue_t;

/* Start the stack and the simulation at time now_ms. Returns 0, or a negative CTRLBUS_ERR_* code
 * for bad options (no write callback). Main loop only. */
int32_t base_glue_init(base_glue_t *glue, const base_glue_options_t *options, uint32_t now_ms);

/* Hand received bytes to the stack's receive ring. ISR-safe (the UART interrupt calls it) as long
 * as only one context feeds; bytes that find the ring full are dropped and counted by the stack.
 * Cost: O(size). */
void base_glue_feed(base_glue_t *glue, const uint8_t *data, size_t size);

/* How many bytes base_glue_feed() would take now (ctrlbus_base_rx_free()). ISR-safe, as feed.
 * Cost: O(1). */
size_t base_glue_rx_free(const base_glue_t *glue);

/* The host's link has a new peer (a new TCP connection): forget the bytes and the half-received
 * frame of the old one. Main loop only. Cost: O(1). */
void base_glue_new_line(base_glue_t *glue);

/* Parse and answer what was fed, run the watchdog and health checks, and step the simulation up
 * to now_ms. Main loop only. Cost: O(bytes fed since the last call) plus the simulation steps. */
void base_glue_poll(base_glue_t *glue, uint32_t now_ms);

#endif
