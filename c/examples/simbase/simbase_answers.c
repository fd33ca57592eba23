/* SPDX-License-Identifier: MIT */
/* The simulated base's answers; see simbase_answers.h. */
#include "simbase_answers.h"

#include <string.h>

#define HEALTH_COMPONENT_POWER 2u
#define HEALTH_TYPE_LOW_BATTERY 1u
#define BATTERY_WARNING_BELOW 30u
#define BATTERY_ERROR_BELOW 10u

/* Copy text into a field of field_size characters plus the NUL, cut if longer. */
static void copy_text(char *field, size_t field_size, const char *text)
{
    memset(field, 0, field_size + 1u);
    if (text != NULL) {
        size_t length = strlen(text);
        memcpy(field, text, length < field_size ? length : field_size);
    }
}

void simbase_answer_connect(const simbase_identity_t *identity, ctrlbus_connect_base_answer_t *out)
{
    memset(out, 0, sizeof *out);
    copy_text(out->model, CTRLBUS_MODEL_LEN, identity->model);
    out->firmware_version = identity->firmware_version;
    out->hardware_version = identity->hardware_version;
    for (size_t i = 0; i < CTRLBUS_SERIAL_WORDS; i++) {
        out->serial[i] = identity->serial[i];
    }
    out->has_firmware_version_suffix = identity->firmware_version_suffix != NULL;
    copy_text(out->firmware_version_suffix, CTRLBUS_FIRMWARE_VERSION_SUFFIX_LEN, identity->firmware_version_suffix);
}

static void to_position(const simbase_mount_t *mount, ctrlbus_position_t *out)
{
    /* Q8 fixed point; the angle is already 0..359 (unsigned on the wire). */
    out->x_mm_q8 = CTRLBUS_Q8(mount->x_mm);
    out->y_mm_q8 = CTRLBUS_Q8(mount->y_mm);
    out->z_mm_q8 = CTRLBUS_Q8(mount->z_mm);
    out->angle_deg_q8 = (uint32_t)CTRLBUS_Q8(mount->angle_deg);
}

void simbase_answer_base_conf(const simbase_t *sim, ctrlbus_get_base_conf_answer_t *out)
{
    memset(out, 0, sizeof *out);
    out->base_type = 0; /* circle */
    out->base_radius_mm_q8 = (uint32_t)CTRLBUS_Q8(simbase_radius_mm(sim));
    out->motor_type = 0; /* two-wheel differential */
    simbase_mount_t mount;
    out->sensor_num = (uint8_t)SIMBASE_SENSOR_COUNT;
    for (uint32_t i = 0; i < SIMBASE_SENSOR_COUNT; i++) {
        (void)simbase_sensor_mount(sim, i, &mount);
        to_position(&mount, &out->sensors[i]);
    }
    out->bumper_num = (uint8_t)SIMBASE_BUMPER_COUNT;
    for (uint32_t i = 0; i < SIMBASE_BUMPER_COUNT; i++) {
        (void)simbase_bumper_mount(sim, i, &mount);
        to_position(&mount, &out->bumpers[i]);
    }
}

void simbase_answer_status(const simbase_t *sim, ctrlbus_get_base_status_answer_t *out)
{
    out->battery_percent = simbase_battery_percent(sim);
    out->power_status = simbase_power_status(sim);
}

void simbase_answer_motor_data(const simbase_t *sim, ctrlbus_get_base_motor_data_answer_t *out)
{
    simbase_wheel_travel_mm(sim, &out->left_distance_mm, &out->right_distance_mm);
    out->status = simbase_motor_status(sim);
}

void simbase_answer_sensor_data(const simbase_t *sim, ctrlbus_get_base_sensor_data_answer_t *out)
{
    for (uint32_t i = 0; i < CTRLBUS_SENSOR_CHANNELS; i++) {
        out->distances_mm_q16[i] = simbase_distance_mm_q16(sim, i);
    }
}

void simbase_answer_bumper_data(const simbase_t *sim, ctrlbus_get_base_bumper_data_answer_t *out)
{
    out->bitmap = simbase_bumper_bitmap(sim);
    out->payload_size = 4;
}

void simbase_answer_charger_data(const simbase_t *sim, uint8_t probes[SIMBASE_PROBE_COUNT],
                                 ctrlbus_get_charger_data_answer_t *out)
{
    simbase_probe_beacons(sim, probes);
    out->beacon_count = (uint8_t)SIMBASE_BEACON_COUNT;
    out->probe_count = (uint8_t)SIMBASE_PROBE_COUNT;
    out->probes = probes;
}

void simbase_apply_motor(simbase_t *sim, const ctrlbus_set_base_motor_request_t *request)
{
    simbase_set_wheel_speeds(sim, request->speeds_mm_s[0], request->speeds_mm_s[1]);
}

void simbase_apply_velocity(simbase_t *sim, const ctrlbus_set_v_and_get_deadreckon_request_t *request,
                            bool with_timestamp, uint32_t uptime_ms,
                            ctrlbus_set_v_and_get_deadreckon_answer_t *out)
{
    simbase_set_velocity(sim, request->vx_mps_q16, request->omega_radps_q16);
    simbase_take_deadreckon(sim, &out->dx_mm_q16, &out->dy_mm_q16, &out->dtheta_deg_q16);
    out->status = simbase_motor_status(sim);
    out->has_timestamp_ms = with_timestamp;
    out->timestamp_ms = with_timestamp ? uptime_ms : 0u;
}

uint8_t simbase_battery_health(const simbase_t *sim, uint32_t *error_code, const char **message)
{
    uint8_t percent = simbase_battery_percent(sim);
    if (percent >= BATTERY_WARNING_BELOW) {
        return 0;
    }
    uint8_t level = percent < BATTERY_ERROR_BELOW ? CTRLBUS_HEALTH_ERROR : CTRLBUS_HEALTH_WARNING;
    *error_code = CTRLBUS_HEALTH_CODE(level, HEALTH_COMPONENT_POWER, HEALTH_TYPE_LOW_BATTERY, 0u);
    *message = level == CTRLBUS_HEALTH_ERROR ? "battery critically low" : "battery low";
    return level;
}
