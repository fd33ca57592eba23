// SPDX-License-Identifier: MIT
// MinimalBase: a robot base that a SLAMWARE Core accepts, with nothing but a board. Wire the
// board's UART to the Core's (115200 8N1, 3.3 V levels). The base stack answers every request;
// this sketch fills in what a base reports (constants here, and two imaginary wheels that move as
// commanded, so that odometry and the motor watchdog can be seen). Put your sensors and motor
// driver where the comments say.
#include <ctrlbus.h>

#define CORE_SERIAL Serial // the UART wired to the Core
#define WHEEL_TRACK_MM 200 // distance between the wheels

// A small board has little RAM: a 300-byte frame buffer still takes every request a Core sends
// in normal use (the stack answers a longer one ERROR 0x0020).
#if defined(__AVR__)
static uint8_t frame_buffer[300];
#else
static uint8_t frame_buffer[CTRLBUS_BASE_FRAME_BUFFER_RECOMMENDED];
#endif
static uint8_t rx_ring[64];
static ctrlbus_base_t base;
static ctrlbus_base_config_t config;

// The imaginary wheels: commanded speeds, and the travel since start-up.
static int32_t left_mm_s, right_mm_s;
static float left_mm, right_mm;
static uint32_t last_ms;
static ctrlbus_diffdrive_pose_t motion; // since the last SET_V_AND_GET_DEADRECKON

static void move_wheels(uint32_t now_ms) // replace with your wheel encoders
{
    float seconds = (float)(now_ms - last_ms) / 1000.0f;
    float left = (float)left_mm_s * seconds, right = (float)right_mm_s * seconds;
    last_ms = now_ms;
    left_mm += left;
    right_mm += right;
    ctrlbus_diffdrive_pose_advance(&motion, left, right, (float)WHEEL_TRACK_MM);
}

// ---- what the base reports and does: one handler per request (ctrlbus/base.h lists them) ----

static int32_t connect_info(void *, ctrlbus_connect_base_answer_t *out)
{
    strncpy(out->model, "arduino base", sizeof out->model - 1);
    out->firmware_version = 0x0100; // 1.0
    out->hardware_version = 1;
    return CTRLBUS_OK;
}

// GET_BASE_CONF is a constant the stack streams: round, 170 mm radius, two-wheel differential,
// no sensors, no bumpers.
static const ctrlbus_get_base_conf_answer_t base_conf = {0, (uint32_t)CTRLBUS_Q8(170), 0, 0, {}, 0, {}};

static int32_t status(void *, ctrlbus_get_base_status_answer_t *out)
{
    out->battery_percent = 80; // read your battery here
    return CTRLBUS_OK;
}

static int32_t motor_data(void *, ctrlbus_get_base_motor_data_answer_t *out)
{
    out->left_distance_mm = (int32_t)left_mm;
    out->right_distance_mm = (int32_t)right_mm;
    return CTRLBUS_OK;
}

static int32_t sensor_data(void *, ctrlbus_get_base_sensor_data_answer_t *) { return CTRLBUS_OK; }

static int32_t bumper_data(void *, ctrlbus_get_base_bumper_data_answer_t *out)
{
    out->bitmap = 0xFFFFFFFFUL; // active low: nothing pressed
    return CTRLBUS_OK;
}

static int32_t charger_data(void *, ctrlbus_get_charger_data_answer_t *) { return CTRLBUS_OK; }

static int32_t set_wheel_speeds(void *, int32_t left, int32_t right) // drive your motors here
{
    left_mm_s = left;
    right_mm_s = right;
    return CTRLBUS_OK;
}

static int32_t set_velocity(void *, const ctrlbus_set_v_and_get_deadreckon_request_t *v,
                            ctrlbus_set_v_and_get_deadreckon_answer_t *out)
{
    int32_t left, right;
    ctrlbus_diffdrive_wheel_speeds(v->vx_mps_q16, v->omega_radps_q16, WHEEL_TRACK_MM, &left, &right);
    set_wheel_speeds(nullptr, left, right);
    ctrlbus_diffdrive_take_deadreckon(&motion, &out->dx_mm_q16, &out->dy_mm_q16, &out->dtheta_deg_q16);
    return CTRLBUS_OK;
}

// ---- the UART glue ----

static int32_t uart_write(void *, const uint8_t *data, size_t size)
{
    CORE_SERIAL.write(data, size);
    return CTRLBUS_OK;
}

void setup()
{
    config.rx_ring = rx_ring;
    config.rx_ring_size = sizeof rx_ring;
    config.frame_buffer = frame_buffer;
    config.frame_buffer_size = sizeof frame_buffer;
    config.limits.max_wheel_mm_s = 1000;
    config.limits.wheel_track_mm = WHEEL_TRACK_MM;
    config.write = uart_write;
    config.connect_info = connect_info;
    config.base_conf = &base_conf;
    config.status = status;
    config.motor_data = motor_data;
    config.sensor_data = sensor_data;
    config.bumper_data = bumper_data;
    config.charger_data = charger_data;
    config.set_wheel_speeds = set_wheel_speeds;
    config.set_velocity = set_velocity;
    ctrlbus_diffdrive_pose_reset(&motion, 0.0f, 0.0f);
    last_ms = millis();
    ctrlbus_base_init(&base, &config, last_ms);
    CORE_SERIAL.begin(115200);
}

void loop()
{
    // Arduino's serial driver already buffers in its interrupt, so bytes are fed from here.
    while (CORE_SERIAL.available() > 0) {
        uint8_t byte = (uint8_t)CORE_SERIAL.read();
        ctrlbus_base_feed(&base, &byte, 1);
    }
    uint32_t now_ms = millis();
    move_wheels(now_ms);
    ctrlbus_base_poll(&base, now_ms);
}
