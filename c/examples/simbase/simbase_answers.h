/* SPDX-License-Identifier: MIT */
/* What the simulated base answers: its state as the ctrlbus message structs (messages.h), and
 * the commands applied to it. This is the application side of a base (the part a base maker
 * writes for their robot); framing, dispatch, errors and the watchdog are the base stack's.
 *
 * Nothing here reads a clock or touches I/O. Main loop only (simbase is not ISR-safe). */
#ifndef CTRLBUS_EXAMPLES_SIMBASE_ANSWERS_H
#define CTRLBUS_EXAMPLES_SIMBASE_ANSWERS_H

#include <stdbool.h>
#include <stdint.h>

#include "ctrlbus/messages.h"
#include "simbase.h"

/* How the simulated base introduces itself (CONNECT_BASE). */
typedef struct {
    const char *model; /* up to 12 characters */
    uint16_t firmware_version;
    uint16_t hardware_version;
    uint32_t serial[CTRLBUS_SERIAL_WORDS];
    /* NULL: the 28-byte answer of the 2018 reference; otherwise the 39-byte answer of the 2020
     * SDK with this suffix (up to 11 characters). */
    const char *firmware_version_suffix;
} simbase_identity_t;

void simbase_answer_connect(const simbase_identity_t *identity, ctrlbus_connect_base_answer_t *out);

/* GET_BASE_CONF: a circular base with the simulation's radius, 5 distance sensors, 2 bumpers. */
void simbase_answer_base_conf(const simbase_t *sim, ctrlbus_get_base_conf_answer_t *out);

void simbase_answer_status(const simbase_t *sim, ctrlbus_get_base_status_answer_t *out);
void simbase_answer_motor_data(const simbase_t *sim, ctrlbus_get_base_motor_data_answer_t *out);

/* GET_BASE_SENSOR_DATA: the 5 sensors in configuration order, the other channels 0. */
void simbase_answer_sensor_data(const simbase_t *sim, ctrlbus_get_base_sensor_data_answer_t *out);

/* GET_BASE_BUMPER_DATA: the 4-byte active-low bitmap (bumpers in bits 0-1, the rest 1). */
void simbase_answer_bumper_data(const simbase_t *sim, ctrlbus_get_base_bumper_data_answer_t *out);

/* GET_CHARGER_DATA: 3 beacons, 3 probes; out->probes points at the caller's probes array, which
 * must outlive the answer. */
void simbase_answer_charger_data(const simbase_t *sim, uint8_t probes[SIMBASE_PROBE_COUNT],
                                 ctrlbus_get_charger_data_answer_t *out);

/* SET_BASE_MOTOR: wheels [0] left and [1] right; [2] and [3] are ignored. */
void simbase_apply_motor(simbase_t *sim, const ctrlbus_set_base_motor_request_t *request);

/* SET_V_AND_GET_DEADRECKON: applies the velocity (vy ignored) and answers the motion since the
 * previous call. With `with_timestamp` the answer has the 2020 SDK's timestamp_ms field, set to
 * `uptime_ms`. */
void simbase_apply_velocity(simbase_t *sim, const ctrlbus_set_v_and_get_deadreckon_request_t *request,
                            bool with_timestamp, uint32_t uptime_ms,
                            ctrlbus_set_v_and_get_deadreckon_answer_t *out);

/* The battery's health, as the reference base judges it: a warning below 30 %, an error below
 * 10 %, both with the reference's low-battery code (component power, type 0x01, index 0).
 * Returns 0 (healthy), CTRLBUS_HEALTH_WARNING or CTRLBUS_HEALTH_ERROR; for the last two
 * *error_code and *message (a string constant) say what to register. */
uint8_t simbase_battery_health(const simbase_t *sim, uint32_t *error_code, const char **message);

#endif
