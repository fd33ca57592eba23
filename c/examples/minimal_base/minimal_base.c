/* SPDX-License-Identifier: MIT */
/* The smallest complete robot base on the ctrlbus base stack: it answers the 13 mandatory requests
 * of the SLAMWARE Control Bus (docs/protocol.md §5) with constants and a robot that exists only as
 * two wheel odometers, enough to make motion commands and the motor watchdog observable.
 * The board is behind c/ports/port.h, and the UART touches this file in two functions only,
 * uart_write(), port_uart_received() and port_uart_room(): the same file runs on a host (host_port.c, a pty) and on
 * every board of c/ports/. What the stack does by itself (error answers, validation, watchdog,
 * inter-byte timeout, SYNC/ECHO, POLL_BASE_CMD, HEALTH_MGMT) is listed in ctrlbus/base.h. */
#include <stdint.h>

#include "ctrlbus/base.h"
#include "ctrlbus/diffdrive.h"
#include "port.h"

/* The receive ring holds what arrives between two polls; the frame buffer is the largest request
 * accepted (its max_frame, docs/protocol.md §3.5), by default the reference base's 512 bytes,
 * which also hold the Core's flushing SYNC (§11.1). A larger frame is answered ERROR 0x0020: the
 * Uno's build passes 64 bytes for both, which hold every other request a Core sends (at most 22
 * bytes); c/ports/README.md says what the smaller buffer changes. */
#ifndef MINIMAL_BASE_RX_RING_SIZE
#define MINIMAL_BASE_RX_RING_SIZE 256u
#endif
#ifndef MINIMAL_BASE_FRAME_BUFFER_SIZE
#define MINIMAL_BASE_FRAME_BUFFER_SIZE CTRLBUS_BASE_FRAME_BUFFER_RECOMMENDED
#endif
/* Where const data stays in flash (ARM, RISC-V) the GET_BASE_CONF constant costs no RAM. avr-gcc
 * copies const data into RAM unless it is PROGMEM, which the stack reads with memcpy_P when the
 * library is built with CTRLBUS_CONST_IN_FLASH (ctrlbus_config.h): the Uno's build does. */
#if CTRLBUS_CONST_IN_FLASH && defined(__AVR__)
#include <avr/pgmspace.h>
#define MINIMAL_BASE_IN_FLASH PROGMEM
#else
#define MINIMAL_BASE_IN_FLASH
#endif
/* 0: the stack's 10 ms. Emulators and hosts deliver bytes in bursts and pass 100. */
#ifndef MINIMAL_BASE_FRAME_TIMEOUT_MS
#define MINIMAL_BASE_FRAME_TIMEOUT_MS 0u
#endif

#define WHEEL_TRACK_MM 200
#define MAX_WHEEL_MM_S 1000u

/* The whole robot: commanded wheel speeds and what the wheels have travelled. The wheels move at
 * constant speed between two commands, so the travel is brought up to date only when it is read
 * or a speed changes: no work while the robot stands still. */
typedef struct {
    uint32_t now_ms, last_ms; /* the main loop's time, the time of the travel below */
    int32_t left_mm_s, right_mm_s;
    int32_t left_mm, right_mm, left_um, right_um; /* travel: whole mm, then the rest in um */
    ctrlbus_diffdrive_pose_t motion; /* since the last SET_V_AND_GET_DEADRECKON */
} robot_t;

static robot_t robot;
static ctrlbus_base_t base;

static void wheel_advance(int32_t *mm, int32_t *um, int32_t travel_um)
{
    *um += travel_um;
    *mm += *um / 1000;
    *um %= 1000;
}

/* mm/s times ms is um; the watchdog stops the wheels within a second, so no product overflows. */
static void robot_advance(void)
{
    int32_t elapsed_ms = (int32_t)(robot.now_ms - robot.last_ms);
    int32_t left_um = robot.left_mm_s * elapsed_ms, right_um = robot.right_mm_s * elapsed_ms;
    robot.last_ms = robot.now_ms;
    wheel_advance(&robot.left_mm, &robot.left_um, left_um);
    wheel_advance(&robot.right_mm, &robot.right_um, right_um);
    ctrlbus_diffdrive_pose_advance(&robot.motion, (float)left_um / 1000.0f,
                                   (float)right_um / 1000.0f, (float)WHEEL_TRACK_MM);
}

/* ---- the handlers: one per request the application answers; the stack zeroes *out first --- */

static int32_t connect_info(void *context, ctrlbus_connect_base_answer_t *out)
{
    static const char model[] = "minimal";
    (void)context;
    for (uint8_t i = 0; i < sizeof model; i++) {
        out->model[i] = model[i];
    }
    out->firmware_version = 0x0100u; /* 1.0 */
    out->hardware_version = 1u;
    out->serial[0] = 0x12345678u;
    return CTRLBUS_OK;
}

/* GET_BASE_CONF: round (type 0), radius 170 mm, two-wheel differential (motor type 0), no sensor,
 * no bumper. The stack streams it from here, field by field. */
static const ctrlbus_get_base_conf_answer_t base_conf MINIMAL_BASE_IN_FLASH = {
    .base_radius_mm_q8 = (uint32_t)CTRLBUS_Q8(170)};

static int32_t status(void *context, ctrlbus_get_base_status_answer_t *out)
{
    (void)context;
    out->battery_percent = 80; /* not charging */
    return CTRLBUS_OK;
}

static int32_t motor_data(void *context, ctrlbus_get_base_motor_data_answer_t *out)
{
    (void)context;
    robot_advance();
    out->left_distance_mm = robot.left_mm;
    out->right_distance_mm = robot.right_mm;
    return CTRLBUS_OK;
}

static int32_t sensor_data(void *context, ctrlbus_get_base_sensor_data_answer_t *out)
{
    (void)context, (void)out; /* no sensor: 16 zero distances */
    return CTRLBUS_OK;
}

static int32_t bumper_data(void *context, ctrlbus_get_base_bumper_data_answer_t *out)
{
    (void)context;
    out->bitmap = 0xFFFFFFFFu; /* active low: nothing pressed */
    return CTRLBUS_OK;
}

static int32_t charger_data(void *context, ctrlbus_get_charger_data_answer_t *out)
{
    (void)context, (void)out; /* no beacon, no probe */
    return CTRLBUS_OK;
}

/* SET_BASE_MOTOR, and the watchdog's stop: the stack's limits keep both within MAX_WHEEL_MM_S. */
static int32_t set_wheel_speeds(void *context, int32_t left_mm_s, int32_t right_mm_s)
{
    (void)context;
    robot_advance();
    robot.left_mm_s = left_mm_s;
    robot.right_mm_s = right_mm_s;
    return CTRLBUS_OK;
}

static int32_t set_velocity(void *context, const ctrlbus_set_v_and_get_deadreckon_request_t *v,
                            ctrlbus_set_v_and_get_deadreckon_answer_t *out)
{
    (void)context;
    robot_advance();
    ctrlbus_diffdrive_wheel_speeds(v->vx_mps_q16, v->omega_radps_q16, WHEEL_TRACK_MM,
                                   &robot.left_mm_s, &robot.right_mm_s);
    ctrlbus_diffdrive_take_deadreckon(&robot.motion, &out->dx_mm_q16, &out->dy_mm_q16,
                                      &out->dtheta_deg_q16);
    return CTRLBUS_OK;
}

/* ---- the UART glue: the only functions that touch the link ---------------------------------- */

static int32_t uart_write(void *context, const uint8_t *data, size_t size)
{
    (void)context;
    port_uart_write(data, size);
    return CTRLBUS_OK;
}

void port_uart_received(uint8_t byte) /* the UART receive interrupt */
{
    (void)ctrlbus_base_feed_byte(&base, byte); /* a full ring drops the byte and counts it */
}

size_t port_uart_room(void) /* asked first: the port leaves a byte in the UART rather than drop it */
{
    return ctrlbus_base_rx_free(&base);
}

/* ---- start-up and the main loop ------------------------------------------------------------- */

int main(void)
{
    static uint8_t rx_ring[MINIMAL_BASE_RX_RING_SIZE];
    static uint8_t frame_buffer[MINIMAL_BASE_FRAME_BUFFER_SIZE];
    static const ctrlbus_base_config_t config = {
        .rx_ring = rx_ring, .rx_ring_size = sizeof rx_ring,
        .frame_buffer = frame_buffer, .frame_buffer_size = sizeof frame_buffer,
        .frame_timeout_ms = MINIMAL_BASE_FRAME_TIMEOUT_MS,
        .limits = {.max_wheel_mm_s = MAX_WHEEL_MM_S, .wheel_track_mm = WHEEL_TRACK_MM},
        .write = uart_write,
        .connect_info = connect_info, .base_conf = &base_conf, .status = status,
        .motor_data = motor_data, .sensor_data = sensor_data, .bumper_data = bumper_data,
        .charger_data = charger_data, .set_wheel_speeds = set_wheel_speeds,
        .set_velocity = set_velocity,
    };
    ctrlbus_diffdrive_pose_reset(&robot.motion, 0.0f, 0.0f);
    /* The stack first, then the UART interrupt that feeds it. */
    if (ctrlbus_base_init(&base, &config, 0) != CTRLBUS_OK) {
        return 1;
    }
    port_init();
    for (;;) {
        robot.now_ms = port_millis();
        ctrlbus_base_poll(&base, robot.now_ms);
        port_idle();
    }
}
