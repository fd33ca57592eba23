/* SPDX-License-Identifier: MIT */
/* base_glue: the simulated base served by the ctrlbus base stack; see base_glue.h. */
#include "base_glue.h"

#include <string.h>

#define DEFAULT_TIME_SCALE_PERCENT 100u
/* The reference's low-battery codes (power component, type 0x01, index 0). */
#define LOW_BATTERY_WARNING CTRLBUS_HEALTH_CODE(CTRLBUS_HEALTH_WARNING, 2u, 1u, 0u)
#define LOW_BATTERY_ERROR CTRLBUS_HEALTH_CODE(CTRLBUS_HEALTH_ERROR, 2u, 1u, 0u)

/* ---- the handlers: each answers from the simulation or applies the command to it ------------ */

static int32_t connect_info(void *context, ctrlbus_connect_base_answer_t *out)
{
    const base_glue_t *glue = context;
    simbase_answer_connect(&glue->identity, out);
    return CTRLBUS_OK;
}

static int32_t status(void *context, ctrlbus_get_base_status_answer_t *out)
{
    const base_glue_t *glue = context;
    simbase_answer_status(&glue->sim, out);
    return CTRLBUS_OK;
}

static int32_t motor_data(void *context, ctrlbus_get_base_motor_data_answer_t *out)
{
    const base_glue_t *glue = context;
    simbase_answer_motor_data(&glue->sim, out);
    return CTRLBUS_OK;
}

static int32_t sensor_data(void *context, ctrlbus_get_base_sensor_data_answer_t *out)
{
    const base_glue_t *glue = context;
    simbase_answer_sensor_data(&glue->sim, out);
    return CTRLBUS_OK;
}

static int32_t bumper_data(void *context, ctrlbus_get_base_bumper_data_answer_t *out)
{
    const base_glue_t *glue = context;
    simbase_answer_bumper_data(&glue->sim, out);
    return CTRLBUS_OK;
}

static int32_t charger_data(void *context, ctrlbus_get_charger_data_answer_t *out)
{
    base_glue_t *glue = context;
    simbase_answer_charger_data(&glue->sim, glue->probes, out);
    return CTRLBUS_OK;
}

/* SET_BASE_MOTOR, and the motor watchdog's stop (the stack calls it with 0, 0). */
static int32_t set_wheel_speeds(void *context, int32_t left_mm_s, int32_t right_mm_s)
{
    base_glue_t *glue = context;
    simbase_set_wheel_speeds(&glue->sim, left_mm_s, right_mm_s);
    return CTRLBUS_OK;
}

static int32_t set_velocity(void *context,
                            const ctrlbus_set_v_and_get_deadreckon_request_t *velocity,
                            ctrlbus_set_v_and_get_deadreckon_answer_t *out)
{
    base_glue_t *glue = context;
    /* No timestamp of our own: with the sdk2020 profile the stack sends its uptime. */
    simbase_apply_velocity(&glue->sim, velocity, false, 0u, out);
    return CTRLBUS_OK;
}

static void reboot(void *context)
{
    base_glue_t *glue = context;
    glue->options.reboot(glue->options.reboot_context);
}

/* ---- time and health ------------------------------------------------------------------------ */

/* Steps the simulation by the real time since the last poll, scaled. */
static void step_simulation(base_glue_t *glue, uint32_t now_ms)
{
    uint32_t elapsed_ms = now_ms - glue->last_poll_ms;
    glue->last_poll_ms = now_ms;
    if (elapsed_ms > 10000u) {
        elapsed_ms = 10000u; /* after a long stall, do not try to catch up (simbase_step agrees) */
    }
    uint32_t scaled = elapsed_ms * glue->options.time_scale_percent + glue->sim_remainder;
    glue->sim_remainder = scaled % 100u;
    simbase_step(&glue->sim, scaled / 100u);
}

/* The battery's health as the reference judges it: one of the two low-battery codes, or none. */
static void evaluate_health(base_glue_t *glue)
{
    uint32_t code = 0;
    const char *message = NULL;
    uint8_t level = simbase_battery_health(&glue->sim, &code, &message);
    if (level == 0u) {
        (void)ctrlbus_base_health_clear(&glue->base, LOW_BATTERY_WARNING);
        (void)ctrlbus_base_health_clear(&glue->base, LOW_BATTERY_ERROR);
        return;
    }
    uint32_t other = code == LOW_BATTERY_WARNING ? LOW_BATTERY_ERROR : LOW_BATTERY_WARNING;
    (void)ctrlbus_base_health_clear(&glue->base, other);
    (void)ctrlbus_base_health_add(&glue->base, code, message);
}

/* The stack's limits from the simulated robot: its top wheel speed (or the option's) and its
 * wheel track, so (vx, omega) is scaled as a whole and a turn stays the same turn. */
static void set_limits(base_glue_t *glue)
{
    int32_t limit = glue->options.max_wheel_mm_s;
    if (limit < 0) {
        return;
    }
    if (limit == 0) {
        limit = glue->sim.config.max_wheel_speed_mm_s;
    }
    int32_t track = 2 * glue->sim.config.half_track_mm;
    const int32_t field_max = (int32_t)UINT16_MAX; /* both limits are u16 fields */
    glue->config.limits.max_wheel_mm_s = (uint16_t)(limit < field_max ? limit : field_max);
    glue->config.limits.wheel_track_mm = (uint16_t)(track < field_max ? track : field_max);
}

/* ---- the interface -------------------------------------------------------------------------- */

int32_t base_glue_init(base_glue_t *glue, const base_glue_options_t *options, uint32_t now_ms)
{
    if (glue == NULL || options == NULL || options->write == NULL) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    memset(glue, 0, sizeof *glue);
    glue->options = *options;
    if (glue->options.time_scale_percent == 0u) {
        glue->options.time_scale_percent = DEFAULT_TIME_SCALE_PERCENT;
    }
    simbase_init(&glue->sim, &glue->options.sim);
    simbase_answer_base_conf(&glue->sim, &glue->base_conf); /* the geometry never changes */
    glue->identity.model = "ctrlbus sim";
    glue->identity.firmware_version =
        (uint16_t)((CTRLBUS_VERSION_MAJOR << 8) | CTRLBUS_VERSION_MINOR);
    glue->identity.hardware_version = options->hardware_version;
    glue->identity.serial[0] = 0x6C727463u; /* "ctrl" */
    glue->identity.serial[1] = 0x00737562u; /* "bus" */
    glue->identity.serial[2] = options->hardware_version;
    glue->last_poll_ms = now_ms;

    ctrlbus_base_config_t *config = &glue->config;
    config->rx_ring = glue->rx_ring;
    config->rx_ring_size = BASE_GLUE_RX_RING_SIZE;
    config->frame_buffer = glue->frame_buffer;
    config->frame_buffer_size = BASE_GLUE_FRAME_BUFFER_SIZE;
    config->health_entries = glue->health;
    config->health_capacity = BASE_GLUE_HEALTH_ENTRIES;
    config->profile = options->sdk2020_sizes ? CTRLBUS_PROFILE_SDK2020 : CTRLBUS_PROFILE_REFERENCE;
    config->frame_timeout_ms = options->frame_timeout_ms;
    config->binary_config = options->binary_config;
    config->binary_config_size = options->binary_config_size;
    config->watchdog_ms = options->watchdog_off ? CTRLBUS_BASE_WATCHDOG_OFF : options->watchdog_ms;
    set_limits(glue);
    config->write = options->write;
    config->write_context = options->write_context;
    config->context = glue;
    config->connect_info = connect_info;
    config->base_conf = &glue->base_conf;
    config->status = status;
    config->motor_data = motor_data;
    config->sensor_data = sensor_data;
    config->bumper_data = bumper_data;
    config->charger_data = charger_data;
    config->set_wheel_speeds = set_wheel_speeds;
    config->set_velocity = set_velocity;
    config->reboot = options->reboot != NULL ? reboot : NULL;
    return ctrlbus_base_init(&glue->base, config, now_ms);
}

void base_glue_feed(base_glue_t *glue, const uint8_t *data, size_t size)
{
    (void)ctrlbus_base_feed(&glue->base, data, size);
}

size_t base_glue_rx_free(const base_glue_t *glue)
{
    return ctrlbus_base_rx_free(&glue->base);
}

void base_glue_new_line(base_glue_t *glue)
{
    ctrlbus_base_reset_line(&glue->base);
}

void base_glue_poll(base_glue_t *glue, uint32_t now_ms)
{
    /* The robot moves up to now before the stack answers (or its watchdog stops it). */
    step_simulation(glue, now_ms);
    evaluate_health(glue);
    ctrlbus_base_poll(&glue->base, now_ms);
}
