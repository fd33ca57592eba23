/* SPDX-License-Identifier: MIT */
/* Unit tests of the base stack (ctrlbus/base.h): every request, every fault answer, profiles,
 * the motor watchdog on a fake clock, velocity limits, health, the command queue, reboot, the
 * receive ring fed from a simulated interrupt and from a second thread, and the shared vectors'
 * base answers. */
#define _POSIX_C_SOURCE 200809L /* pthread, nanosleep */

#include <pthread.h>
#include <stdio.h>
#include <string.h>
#include <time.h>

#include "ctrlbus/base.h"
#include "ctrlbus/diffdrive.h"
#include "ctrlbus/frame.h"
#include "ctrlbus/messages.h"
#include "ctrlbus_vectors.h"
#include "harness.h"

/* ---- the fixture: an application that records what the stack asks of it -------------------- */

typedef struct {
    int32_t fail_with; /* what the data handlers return (CTRLBUS_OK normally) */
    int wheel_calls;
    int32_t left_mm_s;
    int32_t right_mm_s;
    int velocity_calls;
    ctrlbus_set_v_and_get_deadreckon_request_t velocity;
    bool give_timestamp;
    int stop_calls;
    int event_calls;
    uint8_t last_event;
    int reboot_calls;
    size_t output_at_reboot; /* bytes written when the reboot handler ran */
    int health_at_reboot;    /* what the reboot handler found */
    int commands_at_reboot;
    const uint8_t *fed_at_reboot; /* bytes the reboot handler feeds (a host's reader thread) */
    size_t fed_at_reboot_len;
    int dfu_calls;
    int line_calls;
    bool line_low;
    bool model_not_ascii;
    bool suffix;
    uint8_t probes[3];
} app_t;

static app_t app;
static uint32_t now;

static uint8_t rx_ring[4096];
static uint8_t frame_buffer[CTRLBUS_FRAME_MAX];
#if CTRLBUS_CONFIG_HEALTH
static ctrlbus_base_health_entry_t health_storage[4];
#endif
#if CTRLBUS_CONFIG_COMMAND_QUEUE
static uint8_t command_storage[3];
#endif
static const uint8_t BLOB[300] = {0x50, 0x01, 0x04, 0x30, 0x07, 'c', 't', 'r', 'l', 'b', 'u', 's'};
static ctrlbus_decoder_stats_t decoder_stats;

static ctrlbus_base_config_t config;
static ctrlbus_base_t base;

/* Everything the base writes, and how far the test has read it. */
static uint8_t output[1u << 20];
static size_t output_len;
static size_t output_read;
static int32_t write_fails_with; /* 0: writes succeed */
static void (*on_write)(void); /* runs inside every write call: a simulated interrupt */

static int32_t capture_write(void *context, const uint8_t *data, size_t len)
{
    (void)context;
    if (on_write != NULL) {
        on_write();
    }
    if (write_fails_with != 0) {
        return write_fails_with;
    }
    if (len > sizeof output - output_len) {
        harness_fail(__FILE__, __LINE__, "output capture full");
        return CTRLBUS_ERR_IO;
    }
    memcpy(output + output_len, data, len);
    output_len += len;
    return CTRLBUS_OK;
}

static int32_t app_connect(void *context, ctrlbus_connect_base_answer_t *out)
{
    (void)context;
    strcpy(out->model, app.model_not_ascii ? "caf\xe9" : "test base");
    out->firmware_version = 0x0114;
    out->hardware_version = 7;
    out->serial[0] = 0x11111111u;
    out->serial[1] = 0x22222222u;
    out->serial[2] = 0x33333333u;
    if (app.suffix) {
        out->has_firmware_version_suffix = true;
        strcpy(out->firmware_version_suffix, "rc1");
    }
    return app.fail_with;
}

/* GET_BASE_CONF's answer: the application's struct, streamed from where it is. */
static ctrlbus_get_base_conf_answer_t app_base_conf;

static void app_base_conf_reset(void)
{
    memset(&app_base_conf, 0, sizeof app_base_conf);
    app_base_conf.base_radius_mm_q8 = 170u * 256u;
    app_base_conf.sensor_num = 1;
    app_base_conf.sensors[0].x_mm_q8 = 170 * 256;
    app_base_conf.bumper_num = 2;
    app_base_conf.bumpers[1].angle_deg_q8 = 315u * 256u;
}

static int32_t app_status(void *context, ctrlbus_get_base_status_answer_t *out)
{
    (void)context;
    out->battery_percent = 80;
    out->power_status = CTRLBUS_POWER_CHARGING | CTRLBUS_POWER_DC_CONNECTED;
    return app.fail_with;
}

static int32_t app_motor_data(void *context, ctrlbus_get_base_motor_data_answer_t *out)
{
    (void)context;
    out->left_distance_mm = -5;
    out->right_distance_mm = 1234;
    out->status = CTRLBUS_MOTOR_STALL;
    return app.fail_with;
}

static int32_t app_sensor_data(void *context, ctrlbus_get_base_sensor_data_answer_t *out)
{
    (void)context;
    for (uint32_t i = 0; i < CTRLBUS_SENSOR_CHANNELS; i++) {
        out->distances_mm_q16[i] = i * 65536u;
    }
    return app.fail_with;
}

static int32_t app_bumper_data(void *context, ctrlbus_get_base_bumper_data_answer_t *out)
{
    (void)context;
    out->bitmap = 0xFEu; /* bumper 0 pressed (active low) */
    out->payload_size = 1; /* the 2018 firmware's one byte */
    return app.fail_with;
}

static int32_t app_charger_data(void *context, ctrlbus_get_charger_data_answer_t *out)
{
    (void)context;
    app.probes[0] = 0x01;
    app.probes[1] = 0x02;
    app.probes[2] = 0x04;
    out->beacon_count = 3;
    out->probe_count = 3;
    out->probes = app.probes;
    return app.fail_with;
}

static int32_t app_set_wheel_speeds(void *context, int32_t left_mm_s, int32_t right_mm_s)
{
    (void)context;
    app.wheel_calls++;
    app.left_mm_s = left_mm_s;
    app.right_mm_s = right_mm_s;
    return app.fail_with;
}

static int32_t app_set_velocity(void *context,
                                const ctrlbus_set_v_and_get_deadreckon_request_t *velocity,
                                ctrlbus_set_v_and_get_deadreckon_answer_t *out)
{
    (void)context;
    app.velocity_calls++;
    app.velocity = *velocity;
    out->dx_mm_q16 = 100 * 65536;
    out->dy_mm_q16 = -1;
    out->dtheta_deg_q16 = 90 * 65536;
    out->status = 0;
    if (app.give_timestamp) {
        out->has_timestamp_ms = true;
        out->timestamp_ms = 4242;
    }
    return app.fail_with;
}

static void app_stop_motors(void *context)
{
    (void)context;
    app.stop_calls++;
}

static int32_t app_on_event(void *context, uint8_t event)
{
    (void)context;
    app.event_calls++;
    app.last_event = event;
    return app.fail_with;
}

static void app_reboot(void *context)
{
    (void)context;
    app.reboot_calls++;
    app.output_at_reboot = output_len;
    app.health_at_reboot = ctrlbus_base_health_count(&base);
    app.commands_at_reboot = ctrlbus_base_commands_pending(&base);
    if (app.fed_at_reboot != NULL) {
        (void)ctrlbus_base_feed(&base, app.fed_at_reboot, app.fed_at_reboot_len);
    }
}

static void app_enter_dfu(void *context)
{
    (void)context;
    app.dfu_calls++;
    app.output_at_reboot = output_len;
}

static void app_command_line(void *context, bool asserted)
{
    (void)context;
    app.line_calls++;
    app.line_low = asserted;
}

/* A configuration with every handler and every optional buffer that this build's feature
 * switches allow (ctrlbus/ctrlbus_config.h). */
static ctrlbus_base_config_t full_config(void)
{
    ctrlbus_base_config_t c;
    memset(&c, 0, sizeof c);
    c.rx_ring = rx_ring;
    c.rx_ring_size = sizeof rx_ring;
    c.frame_buffer = frame_buffer;
    c.frame_buffer_size = CTRLBUS_BASE_FRAME_BUFFER_RECOMMENDED;
#if CTRLBUS_CONFIG_HEALTH
    c.health_entries = health_storage;
    c.health_capacity = (uint8_t)(sizeof health_storage / sizeof health_storage[0]);
#endif
#if CTRLBUS_CONFIG_COMMAND_QUEUE
    c.command_queue = command_storage;
    c.command_queue_size = sizeof command_storage;
#endif
#if CTRLBUS_CONFIG_CONF_ADV
    c.binary_config = BLOB;
    c.binary_config_size = sizeof BLOB;
#endif
    c.decoder_stats = &decoder_stats;
    c.write = capture_write;
    c.connect_info = app_connect;
    app_base_conf_reset();
    c.base_conf = &app_base_conf;
    c.status = app_status;
    c.motor_data = app_motor_data;
    c.sensor_data = app_sensor_data;
    c.bumper_data = app_bumper_data;
    c.charger_data = app_charger_data;
    c.set_wheel_speeds = app_set_wheel_speeds;
    c.set_velocity = app_set_velocity;
    c.stop_motors = app_stop_motors;
    c.on_event = app_on_event;
    c.reboot = app_reboot;
    c.enter_dfu = app_enter_dfu;
    c.command_line = app_command_line;
    return c;
}

/* Starts a fresh base with `config` (as the test left it) at time `now`. */
static bool start(void)
{
    memset(&app, 0, sizeof app);
    output_len = output_read = 0;
    write_fails_with = 0;
    on_write = NULL;
    return CHECK_EQ(ctrlbus_base_init(&base, &config, now), CTRLBUS_OK);
}

static void setup(void)
{
    now = 1000;
    config = full_config();
    (void)start();
}

/* ---- talking to it -------------------------------------------------------------------------- */

static void feed(const uint8_t *data, size_t len)
{
    CHECK_EQ(ctrlbus_base_feed(&base, data, len), len);
}

static void feed_hex(const char *hex)
{
    uint8_t bytes[512];
    feed(bytes, harness_unhex(bytes, sizeof bytes, hex));
}

/* Sends one request frame (standard unless is_long) and polls once. */
static void send_frame(uint8_t cmd, const uint8_t *payload, size_t len, bool is_long)
{
    static uint8_t frame[CTRLBUS_FRAME_MAX];
    int32_t size = ctrlbus_frame_encode(frame, sizeof frame, cmd, payload, len,
                                        is_long ? CTRLBUS_FRAME_LONG : CTRLBUS_FRAME_STANDARD);
    if (CHECK(size > 0)) {
        feed(frame, (size_t)size);
    }
    ctrlbus_base_poll(&base, now);
}

static void request(const uint8_t *payload, size_t len)
{
    send_frame(CTRLBUS_CMD_CTRL_BUS, payload, len, false);
}

static void request_hex(const char *hex)
{
    uint8_t payload[64];
    request(payload, harness_unhex(payload, sizeof payload, hex));
}

typedef struct {
    bool is_long;
    uint8_t cmd;
    const uint8_t *payload;
    size_t len;
} answer_t;

/* The next whole answer frame the base wrote; fails the test (and returns false) if there is
 * none or it is malformed. */
static bool next_answer(answer_t *a)
{
    const uint8_t *p = output + output_read;
    size_t available = output_len - output_read;
    if (available < 4 || (p[0] != CTRLBUS_FLAG_STANDARD && p[0] != CTRLBUS_FLAG_LONG)) {
        harness_fail(__FILE__, __LINE__, "no answer frame (%zu bytes left)", available);
        return false;
    }
    a->is_long = p[0] == CTRLBUS_FLAG_LONG;
    size_t header = a->is_long ? 3u : 2u;
    size_t len_field = a->is_long ? (size_t)p[1] | ((size_t)p[2] << 8) : p[1];
    size_t size = header + len_field + 1u;
    if (len_field == 0 || size > available) {
        harness_fail(__FILE__, __LINE__, "truncated answer frame");
        return false;
    }
    uint8_t checksum = 0;
    for (size_t i = 0; i + 1 < size; i++) {
        checksum ^= p[i];
    }
    if (!CHECK_EQ(checksum, p[size - 1])) {
        return false;
    }
    a->cmd = p[header];
    a->payload = p + header + 1;
    a->len = len_field - 1u;
    output_read += size;
    return true;
}

/* Checks that the next answer is ERROR `code` in a long frame. */
static bool expect_error(uint16_t code)
{
    answer_t a;
    if (!next_answer(&a)) {
        return false;
    }
    bool ok = CHECK(a.is_long) && CHECK_EQ(a.cmd, CTRLBUS_CMD_ERROR) && CHECK_EQ(a.len, 2);
    return ok && CHECK_EQ(a.payload[0] | (a.payload[1] << 8), code);
}

/* Checks that the next answer is OK with `size` payload bytes; returns its payload. */
static const uint8_t *expect_ok(size_t size)
{
    answer_t a;
    if (!next_answer(&a)) {
        return NULL;
    }
    if (!CHECK_EQ(a.cmd, CTRLBUS_CMD_OK) || !CHECK_EQ(a.len, size)) {
        if (a.cmd == CTRLBUS_CMD_ERROR && a.len == 2) {
            harness_fail(__FILE__, __LINE__, "ERROR 0x%04X", a.payload[0] | (a.payload[1] << 8));
        }
        return NULL;
    }
    CHECK(a.is_long);
    return a.payload;
}

static bool expect_nothing_more(void)
{
    return CHECK_EQ(output_len - output_read, 0);
}

static uint32_t u32_at(const uint8_t *p)
{
    return (uint32_t)p[0] | ((uint32_t)p[1] << 8) | ((uint32_t)p[2] << 16) | ((uint32_t)p[3] << 24);
}

static void put_u32(uint8_t *p, uint32_t value)
{
    for (int i = 0; i < 4; i++) {
        p[i] = (uint8_t)(value >> (8 * i));
    }
}

static void set_motor(int32_t left, int32_t right)
{
    uint8_t payload[CTRLBUS_SET_BASE_MOTOR_REQUEST_SIZE] = {CTRLBUS_CODE_SET_BASE_MOTOR};
    put_u32(payload + 1, (uint32_t)left);
    put_u32(payload + 5, (uint32_t)right);
    request(payload, sizeof payload);
}

static void set_velocity(int32_t vx, int32_t vy, int32_t omega)
{
    uint8_t payload[CTRLBUS_SET_V_AND_GET_DEADRECKON_REQUEST_SIZE] = {
        CTRLBUS_CODE_SET_V_AND_GET_DEADRECKON};
    put_u32(payload + 1, (uint32_t)vx);
    put_u32(payload + 5, (uint32_t)vy);
    put_u32(payload + 9, (uint32_t)omega);
    request(payload, sizeof payload);
}

/* ---- configuration -------------------------------------------------------------------------- */

static void test_init_refuses_bad_configurations(void)
{
    setup();
    ctrlbus_base_config_t bad;
    CHECK_EQ(ctrlbus_base_init(NULL, &config, 0), CTRLBUS_ERR_ARGUMENT);
    CHECK_EQ(ctrlbus_base_init(&base, NULL, 0), CTRLBUS_ERR_ARGUMENT);
    bad = full_config();
    bad.write = NULL;
    CHECK_EQ(ctrlbus_base_init(&base, &bad, 0), CTRLBUS_ERR_ARGUMENT);
    bad = full_config();
    bad.rx_ring = NULL;
    CHECK_EQ(ctrlbus_base_init(&base, &bad, 0), CTRLBUS_ERR_ARGUMENT);
    bad = full_config();
    bad.rx_ring_size = 1;
    CHECK_EQ(ctrlbus_base_init(&base, &bad, 0), CTRLBUS_ERR_ARGUMENT);
    bad = full_config();
    bad.frame_buffer = NULL;
    CHECK_EQ(ctrlbus_base_init(&base, &bad, 0), CTRLBUS_ERR_ARGUMENT);
    bad = full_config();
    bad.frame_buffer_size = 4;
    CHECK_EQ(ctrlbus_base_init(&base, &bad, 0), CTRLBUS_ERR_ARGUMENT);
    bad = full_config();
    bad.binary_config_size = 65535;
    CHECK_EQ(ctrlbus_base_init(&base, &bad, 0), CTRLBUS_ERR_ARGUMENT);
    bad = full_config();
    bad.profile = CTRLBUS_PROFILE_SDK2020;
    bad.standard_answers = true; /* that master checks for the 0x50 flag */
    CHECK_EQ(ctrlbus_base_init(&base, &bad, 0), CTRLBUS_ERR_ARGUMENT);
    bad = full_config();
    bad.profile = (ctrlbus_base_profile_t)7;
    CHECK_EQ(ctrlbus_base_init(&base, &bad, 0), CTRLBUS_ERR_ARGUMENT);
    /* NULL instances are harmless everywhere. */
    CHECK_EQ(ctrlbus_base_feed(NULL, BLOB, 1), 0);
    ctrlbus_base_poll(NULL, 0);
    CHECK_EQ(ctrlbus_base_health_add(NULL, 1, NULL),
             CTRLBUS_CONFIG_HEALTH ? CTRLBUS_ERR_ARGUMENT : CTRLBUS_ERR_UNSUPPORTED);
    CHECK_EQ(ctrlbus_base_health_clear(NULL, 1),
             CTRLBUS_CONFIG_HEALTH ? CTRLBUS_ERR_ARGUMENT : CTRLBUS_ERR_UNSUPPORTED);
    CHECK_EQ(ctrlbus_base_queue_command(NULL, 0x90),
             CTRLBUS_CONFIG_COMMAND_QUEUE ? CTRLBUS_ERR_ARGUMENT : CTRLBUS_ERR_UNSUPPORTED);
    CHECK_EQ(ctrlbus_base_health_count(NULL), 0);
    CHECK_EQ(ctrlbus_base_commands_pending(NULL), 0);
    ctrlbus_base_clear_commands(NULL);
    ctrlbus_base_counters_t counters;
    ctrlbus_base_counters(NULL, &counters);
    CHECK_EQ(counters.watchdog_trips + counters.clamped_commands + counters.rx_dropped, 0);
}

/* ---- SYNC and ECHO -------------------------------------------------------------------------- */

static void test_sync_and_echo_are_copied_verbatim(void)
{
    setup();
    static const char *const REQUESTS[] = {
        "10 01 00 11",          /* SYNC without filler: the reference's example */
        "10 03 01 AA 55 ED",    /* ECHO AA 55 */
        "50 03 00 01 AA 55 AD", /* the same as a long frame: the answer stays long */
        "50 01 00 00 51",       /* long SYNC without filler */
    };
    for (size_t i = 0; i < sizeof REQUESTS / sizeof REQUESTS[0]; i++) {
        harness_context("%s", REQUESTS[i]);
        uint8_t bytes[16];
        size_t len = harness_unhex(bytes, sizeof bytes, REQUESTS[i]);
        output_len = output_read = 0;
        feed(bytes, len);
        ctrlbus_base_poll(&base, now);
        CHECK_MEM(output, output_len, bytes, len);
    }
    harness_context(NULL);
    /* Any size up to the frame buffer: 300 bytes of ECHO come back as the long frame they were,
     * and a SYNC that fills the 512-byte buffer exactly (507 bytes of filler) too. */
    uint8_t data[508];
    for (size_t i = 0; i < sizeof data; i++) {
        data[i] = (uint8_t)(i * 7u);
    }
    static const size_t SIZES[] = {300, 507};
    for (size_t i = 0; i < 2; i++) {
        uint8_t frame[600];
        uint8_t cmd = i == 0 ? CTRLBUS_CMD_ECHO : CTRLBUS_CMD_SYNC;
        int32_t size =
            ctrlbus_frame_encode(frame, sizeof frame, cmd, data, SIZES[i], CTRLBUS_FRAME_AUTO);
        output_len = output_read = 0;
        feed(frame, (size_t)size);
        ctrlbus_base_poll(&base, now);
        CHECK_MEM(output, output_len, frame, (size_t)size);
        CHECK_EQ(output[0], CTRLBUS_FLAG_LONG);
    }
    /* One byte more than the buffer holds is refused as oversize (0x0020). (Filler without
     * flag bytes: the decoder rescans the bytes after a failed header for frames.) */
    memset(data, 0x55, sizeof data);
    uint8_t frame[600];
    int32_t size =
        ctrlbus_frame_encode(frame, sizeof frame, CTRLBUS_CMD_SYNC, data, 508, CTRLBUS_FRAME_LONG);
    output_len = output_read = 0;
    feed(frame, (size_t)size);
    ctrlbus_base_poll(&base, now);
    expect_error(CTRLBUS_WIRE_ERR_TOO_LONG);
    expect_nothing_more();
}

/* ---- every request -------------------------------------------------------------------------- */

static void test_connect_base(void)
{
    setup();
    request_hex("10 01");
    const uint8_t *p = expect_ok(CTRLBUS_CONNECT_BASE_ANSWER_SIZE);
    if (p != NULL) {
        ctrlbus_connect_base_answer_t a;
        CHECK_EQ(ctrlbus_connect_base_answer_decode(&a, p, CTRLBUS_CONNECT_BASE_ANSWER_SIZE),
                 CTRLBUS_OK);
        CHECK_STR(a.model, "test base");
        CHECK_EQ(a.firmware_version, 0x0114);
        CHECK_EQ(a.hardware_version, 7);
        CHECK_EQ(a.serial[2], 0x33333333u);
    }
    /* The reference profile drops a suffix the handler gives: 28 bytes. */
    app.suffix = true;
    request_hex("10 01");
    expect_ok(CTRLBUS_CONNECT_BASE_ANSWER_SIZE);
    /* Protocol version 2 is unsupported; the handler does not run. */
    request_hex("10 02");
    expect_error(CTRLBUS_WIRE_ERR_UNSUPPORTED);
    expect_nothing_more();
}

static void test_get_base_conf_is_a_long_frame(void)
{
    setup();
    config.standard_answers = true; /* even then: 264 bytes do not fit a standard frame */
    start();
    request_hex("20");
    answer_t a;
    if (next_answer(&a)) {
        CHECK(a.is_long);
        CHECK_EQ(a.cmd, CTRLBUS_CMD_OK);
        CHECK_EQ(a.len, CTRLBUS_GET_BASE_CONF_ANSWER_SIZE);
        ctrlbus_get_base_conf_answer_t conf;
        CHECK_EQ(ctrlbus_get_base_conf_answer_decode(&conf, a.payload, a.len), CTRLBUS_OK);
        CHECK_EQ(conf.base_radius_mm_q8, 170u * 256u);
        CHECK_EQ(conf.sensor_num, 1);
        CHECK_EQ(conf.sensors[0].x_mm_q8, 170 * 256);
        CHECK_EQ(conf.bumpers[1].angle_deg_q8, 315u * 256u);
    }
    expect_nothing_more();
}

static void test_binary_config_is_streamed_from_the_callers_array(void)
{
    setup();
    config.standard_answers = true;
    start();
    request_hex("21");
    answer_t a;
    if (next_answer(&a)) {
        CHECK(a.is_long); /* 300 bytes: a long frame whatever the option */
        CHECK_EQ(a.cmd, CTRLBUS_CMD_OK);
        CHECK_MEM(a.payload, a.len, BLOB, sizeof BLOB);
    }
    /* Without a blob the Core is told to fall back to GET_BASE_CONF. */
    config.standard_answers = false;
    config.binary_config = NULL;
    start();
    request_hex("21");
    expect_error(CTRLBUS_WIRE_ERR_UNSUPPORTED);
    expect_nothing_more();
}

static void test_telemetry_requests(void)
{
    setup();
    request_hex("30");
    const uint8_t *p = expect_ok(2);
    if (p != NULL) {
        CHECK_EQ(p[0], 80);
        CHECK_EQ(p[1], 3);
    }
    request_hex("31");
    p = expect_ok(9);
    if (p != NULL) {
        CHECK_EQ((int32_t)u32_at(p), -5);
        CHECK_EQ(u32_at(p + 4), 1234);
        CHECK_EQ(p[8], CTRLBUS_MOTOR_STALL);
    }
    request_hex("32");
    p = expect_ok(64);
    if (p != NULL) {
        CHECK_EQ(u32_at(p + 4 * 15), 15u * 65536u);
    }
    /* The reference profile keeps the handler's short bumper answer. */
    request_hex("33");
    p = expect_ok(1);
    if (p != NULL) {
        CHECK_EQ(p[0], 0xFE);
    }
    request_hex("34 00");
    p = expect_ok(5);
    if (p != NULL) {
        uint8_t expected[] = {3, 3, 1, 2, 4};
        CHECK_MEM(p, 5, expected, 5);
    }
    request_hex("34 01"); /* only beacon data exists */
    expect_error(CTRLBUS_WIRE_ERR_UNSUPPORTED);
    request_hex("35"); /* no layout is published */
    expect_error(CTRLBUS_WIRE_ERR_UNSUPPORTED);
    expect_nothing_more();
}

static void test_motion_requests(void)
{
    setup();
    set_motor(200, -56);
    expect_ok(0);
    CHECK_EQ(app.wheel_calls, 1);
    CHECK_EQ(app.left_mm_s, 200);
    CHECK_EQ(app.right_mm_s, -56);

    set_velocity(13107, 5, 32768);
    const uint8_t *p = expect_ok(CTRLBUS_SET_V_AND_GET_DEADRECKON_ANSWER_SIZE);
    if (p != NULL) {
        CHECK_EQ(u32_at(p), 100u * 65536u);
        CHECK_EQ((int32_t)u32_at(p + 4), -1);
        CHECK_EQ(u32_at(p + 8), 90u * 65536u);
    }
    CHECK_EQ(app.velocity_calls, 1);
    CHECK_EQ(app.velocity.vx_mps_q16, 13107);
    CHECK_EQ(app.velocity.vy_mps_q16, 5);
    CHECK_EQ(app.velocity.omega_radps_q16, 32768);
    /* The reference profile sends 13 bytes even when the handler gives a timestamp. */
    app.give_timestamp = true;
    set_velocity(0, 0, 0);
    expect_ok(CTRLBUS_SET_V_AND_GET_DEADRECKON_ANSWER_SIZE);
    expect_nothing_more();
}

static void test_events(void)
{
    setup();
    request_hex("60 63");
    expect_ok(0);
    CHECK_EQ(app.last_event, 0x63);
    request_hex("60 EE"); /* unknown events are answered OK too */
    expect_ok(0);
    CHECK_EQ(app.event_calls, 2);
    config.on_event = NULL; /* ignoring events is fine: still OK */
    start();
    request_hex("60 65");
    expect_ok(0);
    expect_nothing_more();
}

static void test_unimplemented_requests_are_answered_unsupported(void)
{
    setup();
    ctrlbus_base_config_t empty = full_config();
    empty.connect_info = NULL;
    empty.base_conf = NULL;
    empty.binary_config = NULL;
    empty.status = NULL;
    empty.motor_data = NULL;
    empty.sensor_data = NULL;
    empty.bumper_data = NULL;
    empty.charger_data = NULL;
    empty.set_wheel_speeds = NULL;
    empty.set_velocity = NULL;
    empty.reboot = NULL;
    empty.enter_dfu = NULL;
    config = empty;
    start();
    static const char *const REQUESTS[] = {
        "10 01", "20", "21", "30", "31", "32", "33", "34 00", "35",
        "40 01 00 00 00 01 00 00 00 00 00 00 00 00 00 00 00",
        "41 00 00 01 00 00 00 00 00 00 00 00 00",
    };
    for (size_t i = 0; i < sizeof REQUESTS / sizeof REQUESTS[0]; i++) {
        harness_context("%s", REQUESTS[i]);
        request_hex(REQUESTS[i]);
        expect_error(CTRLBUS_WIRE_ERR_UNSUPPORTED);
    }
    harness_context(NULL);
    uint8_t reboot = CTRLBUS_BASE_CMD_REBOOT;
    uint8_t dfu = CTRLBUS_BASE_CMD_ENTER_DFU;
    send_frame(CTRLBUS_CMD_BASE_CMD, &reboot, 1, false);
    expect_error(CTRLBUS_WIRE_ERR_UNSUPPORTED);
    send_frame(CTRLBUS_CMD_BASE_CMD, &dfu, 1, false);
    expect_error(CTRLBUS_WIRE_ERR_UNSUPPORTED);
    /* What the stack answers itself works without any handler. */
    request_hex("50");
    expect_ok(0);
    request_hex("5F");
    expect_ok(0);
    request_hex("60 63");
    expect_ok(0);
    request_hex("90 01");
    expect_ok(2);
    expect_nothing_more();
    /* A base without set_wheel_speeds or set_velocity never moved: a motion request it cannot
     * execute does not arm a trip. */
    now += 5000;
    ctrlbus_base_poll(&base, now);
    ctrlbus_base_counters_t counters;
    ctrlbus_base_counters(&base, &counters);
    CHECK_EQ(counters.watchdog_trips, 0);
}

static void test_handler_failures(void)
{
    setup();
    app.fail_with = CTRLBUS_ERR_IO;
    static const char *const REQUESTS[] = {"10 01", "30", "31", "32", "33", "34 00", "60 01"};
    for (size_t i = 0; i < sizeof REQUESTS / sizeof REQUESTS[0]; i++) {
        harness_context("%s", REQUESTS[i]);
        request_hex(REQUESTS[i]);
        expect_error(CTRLBUS_WIRE_ERR_OPERATION);
    }
    harness_context(NULL);
    set_motor(1, 1);
    expect_error(CTRLBUS_WIRE_ERR_OPERATION);
    set_velocity(1, 0, 0);
    expect_error(CTRLBUS_WIRE_ERR_OPERATION);
    /* A handler may say "not supported" at run time. */
    app.fail_with = CTRLBUS_ERR_UNSUPPORTED;
    request_hex("30");
    expect_error(CTRLBUS_WIRE_ERR_UNSUPPORTED);
    /* An answer the codec refuses (text that is not ASCII) is an operation failure, found before
     * any byte of it goes out. */
    app.fail_with = CTRLBUS_OK;
    app.model_not_ascii = true;
    request_hex("10 01");
    expect_error(CTRLBUS_WIRE_ERR_OPERATION);
    /* So is a GET_BASE_CONF struct with more than 8 sensors; the struct is read as it is now. */
    app_base_conf.sensor_num = CTRLBUS_CONF_SLOTS + 1u;
    request_hex("20");
    expect_error(CTRLBUS_WIRE_ERR_OPERATION);
    app_base_conf.sensor_num = 2;
    request_hex("20");
    answer_t a;
    if (next_answer(&a)) {
        CHECK_EQ(a.cmd, CTRLBUS_CMD_OK);
        CHECK_EQ(a.len, CTRLBUS_GET_BASE_CONF_ANSWER_SIZE);
        CHECK_EQ(a.payload[5 + 1], 2); /* base_type u8, radius u32, motor_type u8, sensor_num */
    }
    expect_nothing_more();
}

/* ---- what the stack answers to faults (§8) -------------------------------------------------- */

static void test_checksum_failed_set_base_motor_is_not_executed(void)
{
    setup();
    uint8_t payload[CTRLBUS_SET_BASE_MOTOR_REQUEST_SIZE] = {CTRLBUS_CODE_SET_BASE_MOTOR};
    put_u32(payload + 1, 300);
    put_u32(payload + 5, 300);
    uint8_t frame[32];
    int32_t size = ctrlbus_frame_encode(frame, sizeof frame, CTRLBUS_CMD_CTRL_BUS, payload,
                                        sizeof payload, CTRLBUS_FRAME_STANDARD);
    frame[size - 1] ^= 0x01u;
    feed(frame, (size_t)size);
    ctrlbus_base_poll(&base, now);
    expect_error(CTRLBUS_WIRE_ERR_CHECKSUM);
    expect_nothing_more();
    CHECK_EQ(app.wheel_calls, 0);
    /* A corrupted payload byte instead of the checksum byte: the same. */
    frame[size - 1] ^= 0x01u;
    frame[4] ^= 0x40u;
    feed(frame, (size_t)size);
    ctrlbus_base_poll(&base, now);
    expect_error(CTRLBUS_WIRE_ERR_CHECKSUM);
    CHECK_EQ(app.wheel_calls, 0);
    /* And with the reference's quirky code. */
    config.reference_checksum_code = true;
    start();
    feed(frame, (size_t)size);
    ctrlbus_base_poll(&base, now);
    expect_error(CTRLBUS_WIRE_ERR_CHECKSUM_REFERENCE);
    CHECK_EQ(app.wheel_calls, 0);
    expect_nothing_more();
}

static void test_decoder_events(void)
{
    setup();
    /* A burst of garbage: one 0x0010, not one per byte; the frame after it is answered. */
    feed_hex("00 FF 12 34 AB CD EF 01 10 02 F8 30 DA");
    ctrlbus_base_poll(&base, now);
    expect_error(CTRLBUS_WIRE_ERR_NOT_SYNCHRONISED);
    expect_ok(2);
    /* Two gaps, two answers; split across polls changes nothing. */
    feed_hex("AA BB");
    ctrlbus_base_poll(&base, now);
    feed_hex("CC 10 02 F8 30 DA EE");
    ctrlbus_base_poll(&base, now);
    expect_error(CTRLBUS_WIRE_ERR_NOT_SYNCHRONISED);
    expect_ok(2);
    expect_error(CTRLBUS_WIRE_ERR_NOT_SYNCHRONISED);
    /* A long length beyond the 512-byte buffer is refused at once, without waiting for it. */
    feed_hex("50 FE 01");
    ctrlbus_base_poll(&base, now);
    expect_error(CTRLBUS_WIRE_ERR_TOO_LONG);
    /* Empty frames are malformed requests. */
    feed_hex("10 00 10");
    ctrlbus_base_poll(&base, now);
    expect_error(CTRLBUS_WIRE_ERR_FORMAT);
    /* A frame cut short is dropped after the inter-byte timeout (10 ms by default) without an
     * answer; the next request is answered. */
    feed_hex("10 0E F8 41 33");
    ctrlbus_base_poll(&base, now);
    now += 10;
    ctrlbus_base_poll(&base, now); /* exactly the timeout: still waiting */
    expect_nothing_more();
    now += 1;
    ctrlbus_base_poll(&base, now);
    expect_nothing_more();
    request_hex("30");
    expect_ok(2);
    CHECK_EQ(decoder_stats.timeouts, 1);
    expect_nothing_more();
}

static void test_frame_timeout_is_configurable(void)
{
    setup();
    config.frame_timeout_ms = 100;
    start();
    feed_hex("10 02 F8");
    ctrlbus_base_poll(&base, now);
    now += 100;
    ctrlbus_base_poll(&base, now);
    feed_hex("30 DA"); /* 100 ms later is within a 100 ms timeout */
    ctrlbus_base_poll(&base, now);
    expect_ok(2);
    config.frame_timeout_ms = CTRLBUS_BASE_TIMEOUT_OFF;
    start();
    feed_hex("10 02 F8");
    ctrlbus_base_poll(&base, now);
    now += 100000;
    ctrlbus_base_poll(&base, now);
    feed_hex("30 DA");
    ctrlbus_base_poll(&base, now);
    expect_ok(2);
    expect_nothing_more();
}

/* A new peer on the line: its first request is not glued to the old peer's half frame, and
 * nothing else of the session is forgotten. */
static void test_reset_line_forgets_the_half_frame(void)
{
    setup();
    config.frame_timeout_ms = CTRLBUS_BASE_TIMEOUT_OFF;
    start();
    feed_hex("10 02 F8");
    ctrlbus_base_poll(&base, now);
    feed_hex("10"); /* still in the ring: forgotten too */
    ctrlbus_base_reset_line(&base);
    feed_hex("10 02 F8 30 DA"); /* GET_BASE_STATUS */
    ctrlbus_base_poll(&base, now);
    expect_ok(2);
    expect_nothing_more();
    ctrlbus_base_reset_line(NULL); /* harmless */
}

static void test_answer_frame_types(void)
{
    setup();
    request_hex("30");
    answer_t a;
    if (next_answer(&a)) {
        CHECK(a.is_long); /* the reference's way */
    }
    request_hex("30 00");
    if (next_answer(&a)) {
        CHECK(a.is_long);
        CHECK_EQ(a.cmd, CTRLBUS_CMD_ERROR);
    }
    config.standard_answers = true;
    start();
    request_hex("30");
    if (next_answer(&a)) {
        CHECK(!a.is_long);
        CHECK_EQ(a.len, 2);
    }
    request_hex("30 00");
    if (next_answer(&a)) {
        CHECK(!a.is_long);
        CHECK_EQ(a.cmd, CTRLBUS_CMD_ERROR);
    }
    /* The frame type of the request does not matter. */
    uint8_t status = CTRLBUS_CODE_GET_BASE_STATUS;
    send_frame(CTRLBUS_CMD_CTRL_BUS, &status, 1, true);
    if (next_answer(&a)) {
        CHECK(!a.is_long);
    }
    expect_nothing_more();
}

static void test_answers_keep_stream_order(void)
{
    setup();
    /* Several requests and faults in one burst: answered one by one, in order. */
    feed_hex("10 02 F8 30 DA  EE  10 02 F8 30 DB  10 03 01 AA 55 ED  10 03 F8 10 01 FA");
    ctrlbus_base_poll(&base, now);
    expect_ok(2);
    expect_error(CTRLBUS_WIRE_ERR_NOT_SYNCHRONISED);
    expect_error(CTRLBUS_WIRE_ERR_CHECKSUM);
    answer_t a;
    if (next_answer(&a)) {
        CHECK_EQ(a.cmd, CTRLBUS_CMD_ECHO);
    }
    expect_ok(CTRLBUS_CONNECT_BASE_ANSWER_SIZE);
    expect_nothing_more();
}

static void test_a_failing_write_cuts_one_answer_only(void)
{
    setup();
    write_fails_with = CTRLBUS_ERR_IO;
    request_hex("30");
    CHECK_EQ(output_len, 0);
    write_fails_with = 0;
    request_hex("30");
    expect_ok(2);
    expect_nothing_more();
}

/* ---- profiles ------------------------------------------------------------------------------- */

static void test_sdk2020_profile(void)
{
    setup();
    config.profile = CTRLBUS_PROFILE_SDK2020;
    now = 5000;
    start();
    /* CONNECT: 39 bytes, with an empty suffix when the handler gives none. */
    request_hex("10 01");
    const uint8_t *p = expect_ok(CTRLBUS_CONNECT_BASE_ANSWER_SIZE_WITH_SUFFIX);
    if (p != NULL) {
        uint8_t zeros[CTRLBUS_FIRMWARE_VERSION_SUFFIX_LEN] = {0};
        CHECK_MEM(p + 28, CTRLBUS_FIRMWARE_VERSION_SUFFIX_LEN, zeros, sizeof zeros);
    }
    app.suffix = true;
    request_hex("10 01");
    p = expect_ok(CTRLBUS_CONNECT_BASE_ANSWER_SIZE_WITH_SUFFIX);
    if (p != NULL) {
        CHECK_MEM(p + 28, 3, "rc1", 3);
    }
    /* Deadreckon: 17 bytes; the uptime as timestamp unless the handler gives one. */
    now = 6234;
    set_velocity(0, 0, 0);
    p = expect_ok(CTRLBUS_SET_V_AND_GET_DEADRECKON_ANSWER_SIZE_WITH_TIMESTAMP);
    if (p != NULL) {
        CHECK_EQ(u32_at(p + 13), 1234);
    }
    app.give_timestamp = true;
    set_velocity(0, 0, 0);
    p = expect_ok(CTRLBUS_SET_V_AND_GET_DEADRECKON_ANSWER_SIZE_WITH_TIMESTAMP);
    if (p != NULL) {
        CHECK_EQ(u32_at(p + 13), 4242);
    }
    /* Bumpers always 4 bytes, the same value. */
    request_hex("33");
    p = expect_ok(4);
    if (p != NULL) {
        CHECK_EQ(u32_at(p), 0xFEu);
    }
    /* POLL with nothing pending: FF 00, a fixed size for a fixed-size reader. */
    request_hex("50");
    p = expect_ok(2);
    if (p != NULL) {
        CHECK_EQ(p[0], 0xFF);
        CHECK_EQ(p[1], 0x00);
    }
    expect_nothing_more();
}

/* ---- motor watchdog ------------------------------------------------------------------------- */

static void get_health(uint8_t *flags, uint8_t *count)
{
    request_hex("90 01");
    const uint8_t *p = expect_ok(2);
    *flags = p != NULL ? p[0] : 0xEE;
    *count = p != NULL ? p[1] : 0xEE;
}

static void test_watchdog_trips_after_1000_ms_and_shows_in_health(void)
{
    setup();
    const uint32_t poll_period = 7;
    set_motor(150, 150);
    expect_ok(0);
    uint32_t commanded = now;
    uint32_t tripped = 0;
    for (int i = 0; i < 400 && app.stop_calls == 0; i++) {
        now += poll_period;
        ctrlbus_base_poll(&base, now);
        if (app.stop_calls != 0) {
            tripped = now;
        }
    }
    /* More than 1000 ms, at most one poll period more. */
    CHECK(tripped > commanded + 1000u);
    CHECK(tripped <= commanded + 1000u + poll_period);
    CHECK_EQ(app.stop_calls, 1);
    expect_nothing_more(); /* the stack stops the wheels silently; the Core reads health */
    ctrlbus_base_counters_t counters;
    ctrlbus_base_counters(&base, &counters);
    CHECK_EQ(counters.watchdog_trips, 1);

    uint8_t flags = 0;
    uint8_t count = 0;
    get_health(&flags, &count);
#if !CTRLBUS_CONFIG_HEALTH
    /* No registry: the trip is counted, but the Core reads a healthy base. */
    CHECK_EQ(flags, 0);
    CHECK_EQ(count, 0);
    request_hex("90 02 00");
    expect_error(CTRLBUS_WIRE_ERR_OPERATION);
    expect_nothing_more();
    return;
#endif
    CHECK_EQ(flags, CTRLBUS_HEALTH_WARNING);
    CHECK_EQ(count, 1);
    request_hex("90 02 00");
    const uint8_t *p = expect_ok(CTRLBUS_HEALTH_GET_ERROR_ANSWER_SIZE);
    if (p != NULL) {
        CHECK_EQ(u32_at(p), CTRLBUS_HEALTH_WATCHDOG_TRIPPED);
        CHECK_STR((const char *)p + 4, "motor watchdog tripped");
    }
    /* The HEALTH requests fed the watchdog; the silence after them expires idle: the wheels
     * are stopped again (once), but that is no trip. */
    now += 5000;
    ctrlbus_base_poll(&base, now);
    CHECK_EQ(app.stop_calls, 2);
    now += 5000;
    ctrlbus_base_poll(&base, now); /* once per silence */
    CHECK_EQ(app.stop_calls, 2);
    ctrlbus_base_counters(&base, &counters);
    CHECK_EQ(counters.watchdog_trips, 1);

    /* A second trip while the warning is registered counts, but adds no second entry. */
    set_motor(-20, 20);
    expect_ok(0);
    now += 1001;
    ctrlbus_base_poll(&base, now);
    ctrlbus_base_counters(&base, &counters);
    CHECK_EQ(counters.watchdog_trips, 2);
    get_health(&flags, &count);
    CHECK_EQ(count, 1);
    /* The Core clears it; a bad code is an operation error. */
    request_hex("90 03 00 80 03 01");
    expect_ok(0);
    request_hex("90 03 00 80 03 01");
    expect_error(CTRLBUS_WIRE_ERR_OPERATION);
    get_health(&flags, &count);
    CHECK_EQ(flags, 0);
    CHECK_EQ(count, 0);
    request_hex("90 02 00");
    expect_error(CTRLBUS_WIRE_ERR_OPERATION);
    expect_nothing_more();
}

static void test_watchdog_idle_expiry_and_what_feeds_it(void)
{
    setup();
    /* Armed from start-up: the first silence stops the (idle) wheels, but is no trip. */
    now += 1001;
    ctrlbus_base_poll(&base, now);
    CHECK_EQ(app.stop_calls, 1);
    ctrlbus_base_counters_t counters;
    ctrlbus_base_counters(&base, &counters);
    CHECK_EQ(counters.watchdog_trips, 0);
    CHECK_EQ(ctrlbus_base_health_count(&base), 0);

    /* A command of zero speed is no motion either. */
    set_velocity(0, 0, 0);
    expect_ok(13);
    now += 1001;
    ctrlbus_base_poll(&base, now);
    CHECK_EQ(app.stop_calls, 2);
    CHECK_EQ(ctrlbus_base_health_count(&base), 0);

    /* SYNC, ECHO and BASE_CMD do not feed it; a CTRL_BUS frame answered with an error does. */
    set_motor(10, 10);
    expect_ok(0);
    for (int i = 0; i < 9; i++) {
        now += 100;
        feed_hex("10 01 00 11  10 03 01 AA 55 ED  10 02 F9 03 E8");
        ctrlbus_base_poll(&base, now);
    }
    now += 101;
    ctrlbus_base_poll(&base, now);
    CHECK_EQ(app.stop_calls, 3);
    ctrlbus_base_counters(&base, &counters);
    CHECK_EQ(counters.watchdog_trips, 1);

    set_motor(10, 10);
    output_len = output_read = 0;
    for (int i = 0; i < 30; i++) {
        now += 100;
        request_hex("77"); /* unknown request code: ERROR 0x8000, but the Core is alive */
        expect_error(CTRLBUS_WIRE_ERR_UNSUPPORTED);
    }
    CHECK_EQ(app.stop_calls, 3);
}

static void test_watchdog_period_and_off(void)
{
    setup();
    config.watchdog_ms = 200;
    start();
    set_motor(10, 10);
    now += 200;
    ctrlbus_base_poll(&base, now);
    CHECK_EQ(app.stop_calls, 0);
    now += 1;
    ctrlbus_base_poll(&base, now);
    CHECK_EQ(app.stop_calls, 1);

    config.watchdog_ms = CTRLBUS_BASE_WATCHDOG_OFF;
    start();
    set_motor(10, 10);
    now += 100000;
    ctrlbus_base_poll(&base, now);
    CHECK_EQ(app.stop_calls, 0);

    /* Without stop_motors the wheels are stopped through set_wheel_speeds(0, 0). */
    config = full_config();
    config.stop_motors = NULL;
    start();
    set_motor(10, 10);
    now += 1001;
    ctrlbus_base_poll(&base, now);
    CHECK_EQ(app.wheel_calls, 2);
    CHECK_EQ(app.left_mm_s, 0);
    CHECK_EQ(app.right_mm_s, 0);
}

static void test_watchdog_across_clock_wrap(void)
{
    setup();
    now = 0xFFFFFF00u;
    start();
    set_motor(10, 10);
    now += 0x200u; /* wrapped: 512 ms later */
    ctrlbus_base_poll(&base, now);
    CHECK_EQ(app.stop_calls, 0);
    now += 488; /* exactly 1000 ms: not yet */
    ctrlbus_base_poll(&base, now);
    CHECK_EQ(app.stop_calls, 0);
    now += 1;
    ctrlbus_base_poll(&base, now);
    CHECK_EQ(app.stop_calls, 1);
}

/* ---- velocity limits ------------------------------------------------------------------------ */

static void test_wheel_limit_scales_both_wheels(void)
{
    setup();
    config.limits.max_wheel_mm_s = 500;
    start();
    set_motor(1000, 250);
    expect_ok(0);
    CHECK_EQ(app.left_mm_s, 500);
    CHECK_EQ(app.right_mm_s, 125); /* same factor: the curvature is kept */
    set_motor(-250, -1000);
    expect_ok(0);
    CHECK_EQ(app.left_mm_s, -125);
    CHECK_EQ(app.right_mm_s, -500);
    set_motor(INT32_MIN, INT32_MAX);
    expect_ok(0);
    CHECK_EQ(app.left_mm_s, -500);
    CHECK_EQ(app.right_mm_s, 499); /* towards zero: never beyond the limit */
    set_motor(500, -500); /* at the limit: untouched, not counted */
    expect_ok(0);
    CHECK_EQ(app.left_mm_s, 500);
    CHECK_EQ(app.right_mm_s, -500);
    ctrlbus_base_counters_t counters;
    ctrlbus_base_counters(&base, &counters);
    CHECK_EQ(counters.clamped_commands, 3);
    expect_nothing_more();
}

static void test_velocity_limits(void)
{
    setup();
    config.limits.max_vx_mps_q16 = 32768;     /* 0.5 m/s */
    config.limits.max_omega_radps_q16 = 65536; /* 1 rad/s */
    start();
    set_velocity(65536, 7, -3 * 65536);
    expect_ok(13);
    CHECK_EQ(app.velocity.vx_mps_q16, 32768);
    CHECK_EQ(app.velocity.vy_mps_q16, 7); /* passed on: a differential base ignores it */
    CHECK_EQ(app.velocity.omega_radps_q16, -65536);
    set_velocity(INT32_MIN, 0, INT32_MIN);
    expect_ok(13);
    CHECK_EQ(app.velocity.vx_mps_q16, -32768);
    CHECK_EQ(app.velocity.omega_radps_q16, -65536);
    set_velocity(1000, 0, -1000); /* within: untouched */
    expect_ok(13);
    CHECK_EQ(app.velocity.vx_mps_q16, 1000);
    CHECK_EQ(app.velocity.omega_radps_q16, -1000);
    ctrlbus_base_counters_t counters;
    ctrlbus_base_counters(&base, &counters);
    CHECK_EQ(counters.clamped_commands, 2);

    /* With a wheel limit and the wheel track, (vx, omega) are scaled together so that the
     * faster wheel is at the limit: 0.4 m/s and 2 rad/s on a 236 mm track would be 164 and
     * 636 mm/s; limited to 500 mm/s, the right wheel gets 500. */
    config.limits.max_vx_mps_q16 = 0;
    config.limits.max_omega_radps_q16 = 0;
    config.limits.max_wheel_mm_s = 500;
    config.limits.wheel_track_mm = 236;
    start();
    set_velocity(26214, 0, 2 * 65536);
    expect_ok(13);
    int32_t left = 0;
    int32_t right = 0;
    ctrlbus_diffdrive_wheel_speeds(app.velocity.vx_mps_q16, app.velocity.omega_radps_q16, 236,
                                   &left, &right);
    CHECK_EQ(right, 500);
    CHECK(left >= 128 && left <= 129); /* 164 * 500 / 636 = 128.9 */
    /* The turning radius (vx / omega) is kept. */
    double radius_before = 26214.0 / (2.0 * 65536.0);
    double radius_after = (double)app.velocity.vx_mps_q16 / (double)app.velocity.omega_radps_q16;
    CHECK(radius_after > radius_before - 1e-4 && radius_after < radius_before + 1e-4);
    ctrlbus_base_counters(&base, &counters);
    CHECK_EQ(counters.clamped_commands, 1);
    expect_nothing_more();
}

/* ---- health registry ------------------------------------------------------------------------ */

static void test_health_registry(void)
{
    setup();
    const uint32_t low_battery = CTRLBUS_HEALTH_CODE(CTRLBUS_HEALTH_WARNING, 2, 1, 0);
    const uint32_t estop = CTRLBUS_HEALTH_CODE(CTRLBUS_HEALTH_FATAL, 1, 1, 0);
    CHECK_EQ(ctrlbus_base_health_add(&base, low_battery, "battery low"), 1);
    CHECK_EQ(ctrlbus_base_health_add(&base, low_battery, "again"), 0); /* one entry per code */
    CHECK_EQ(ctrlbus_base_health_add(&base, estop, NULL), 1);
    CHECK_EQ(ctrlbus_base_health_add(&base, 5, "0123456789012345678901234567890"), 1); /* 31 */
    CHECK_EQ(ctrlbus_base_health_add(&base, 6, "01234567890123456789012345678901"), /* 32 */
             CTRLBUS_ERR_ARGUMENT);
    CHECK_EQ(ctrlbus_base_health_add(&base, 6, "caf\xe9"), CTRLBUS_ERR_ARGUMENT);
    CHECK_EQ(ctrlbus_base_health_add(&base, 6, "fourth"), 1);
    CHECK_EQ(ctrlbus_base_health_add(&base, 7, "fifth"), CTRLBUS_ERR_TOO_BIG); /* 4 slots */
    CHECK_EQ(ctrlbus_base_health_count(&base), 4);
    uint8_t flags = 0;
    uint8_t count = 0;
    get_health(&flags, &count);
    CHECK_EQ(flags, CTRLBUS_HEALTH_WARNING | CTRLBUS_HEALTH_FATAL);
    CHECK_EQ(count, 4);
    request_hex("90 02 01");
    const uint8_t *p = expect_ok(36);
    if (p != NULL) {
        CHECK_EQ(u32_at(p), estop);
        CHECK_EQ(p[4], 0); /* NULL message: empty */
    }
    request_hex("90 02 02");
    p = expect_ok(36);
    if (p != NULL) {
        CHECK_STR((const char *)p + 4, "0123456789012345678901234567890");
    }
    /* Clearing keeps the order of the rest. */
    CHECK_EQ(ctrlbus_base_health_clear(&base, low_battery), 1);
    CHECK_EQ(ctrlbus_base_health_clear(&base, low_battery), 0);
    request_hex("90 02 00");
    p = expect_ok(36);
    if (p != NULL) {
        CHECK_EQ(u32_at(p), estop);
    }
    request_hex("90 02 02");
    p = expect_ok(36);
    if (p != NULL) {
        CHECK_STR((const char *)p + 4, "fourth");
    }
    request_hex("90 02 03");
    expect_error(CTRLBUS_WIRE_ERR_OPERATION);
    request_hex("90 04"); /* unknown sub-command: 0x8002, the reference's choice */
    expect_error(CTRLBUS_WIRE_ERR_OPERATION);
    expect_nothing_more();
}

static void test_health_without_storage_holds_the_watchdog_warning(void)
{
    setup();
    config.health_entries = NULL;
    start();
    CHECK_EQ(ctrlbus_base_health_add(&base, 5, "app"), CTRLBUS_ERR_TOO_BIG);
    set_motor(10, 10);
    expect_ok(0);
    now += 1001;
    ctrlbus_base_poll(&base, now);
    uint8_t flags = 0;
    uint8_t count = 0;
    get_health(&flags, &count);
    CHECK_EQ(flags, CTRLBUS_HEALTH_WARNING);
    CHECK_EQ(count, 1);
    request_hex("90 02 00");
    const uint8_t *p = expect_ok(36);
    if (p != NULL) {
        CHECK_EQ(u32_at(p), CTRLBUS_HEALTH_WATCHDOG_TRIPPED);
        CHECK_STR((const char *)p + 4, CTRLBUS_HEALTH_WATCHDOG_TRIPPED_MESSAGE);
    }
    request_hex("90 03 00 80 03 01");
    expect_ok(0);
    CHECK_EQ(ctrlbus_base_health_count(&base), 0);
    expect_nothing_more();
}

static void test_full_health_registry_does_not_stop_the_watchdog(void)
{
    setup();
    for (uint32_t code = 1; code <= 4; code++) {
        CHECK_EQ(ctrlbus_base_health_add(&base, code, "x"), 1);
    }
    set_motor(10, 10);
    now += 1001;
    ctrlbus_base_poll(&base, now);
    CHECK_EQ(app.stop_calls, 1);
    ctrlbus_base_counters_t counters;
    ctrlbus_base_counters(&base, &counters);
    CHECK_EQ(counters.watchdog_trips, 1);
    CHECK_EQ(ctrlbus_base_health_count(&base), 4);
}

/* ---- external commands ---------------------------------------------------------------------- */

static void test_external_command_queue(void)
{
    setup();
    request_hex("50");
    expect_ok(0); /* nothing pending: v4's empty OK */
    CHECK_EQ(ctrlbus_base_queue_command(&base, 0xA4), CTRLBUS_OK); /* GO_HOME */
    CHECK(app.line_low);
    CHECK_EQ(app.line_calls, 1);
    CHECK_EQ(ctrlbus_base_queue_command(&base, 0x90), CTRLBUS_OK);
    CHECK_EQ(ctrlbus_base_queue_command(&base, 0x51), CTRLBUS_OK);
    CHECK_EQ(ctrlbus_base_queue_command(&base, 0x52), CTRLBUS_ERR_TOO_BIG); /* 3 slots */
    CHECK_EQ(ctrlbus_base_queue_command(&base, 0x00), CTRLBUS_ERR_ARGUMENT);
    CHECK_EQ(ctrlbus_base_queue_command(&base, 0xFF), CTRLBUS_ERR_ARGUMENT);
    CHECK_EQ(ctrlbus_base_commands_pending(&base), 3);
    CHECK_EQ(app.line_calls, 1);
    static const uint8_t EXPECTED[] = {0xA4, 0x90, 0x51};
    for (size_t i = 0; i < 3; i++) {
        /* The head stays offered until the Core takes it. */
        for (int repeat = 0; repeat < 2; repeat++) {
            request_hex("50");
            const uint8_t *p = expect_ok(2);
            if (p != NULL) {
                CHECK_EQ(p[0], EXPECTED[i]);
                CHECK_EQ(p[1], 0);
            }
        }
        request_hex("5F");
        expect_ok(0);
        if (i == 0) {
            /* Room again: the ring wraps. */
            CHECK_EQ(ctrlbus_base_queue_command(&base, 0xAF), CTRLBUS_OK);
        }
    }
    request_hex("50");
    const uint8_t *p = expect_ok(2);
    if (p != NULL) {
        CHECK_EQ(p[0], 0xAF);
    }
    request_hex("5F");
    expect_ok(0);
    CHECK(!app.line_low); /* released once the queue is empty */
    CHECK_EQ(app.line_calls, 2);
    request_hex("5F"); /* nothing pending: still OK */
    expect_ok(0);
    request_hex("50");
    expect_ok(0);
    CHECK_EQ(app.line_calls, 2);
    /* clear_commands releases the line too. */
    CHECK_EQ(ctrlbus_base_queue_command(&base, 0x80), CTRLBUS_OK);
    ctrlbus_base_clear_commands(&base);
    CHECK(!app.line_low);
    CHECK_EQ(ctrlbus_base_commands_pending(&base), 0);
    expect_nothing_more();
}

static void test_command_queue_without_storage_holds_one(void)
{
    setup();
    config.command_queue = NULL;
    config.command_line = NULL;
    start();
    CHECK_EQ(ctrlbus_base_queue_command(&base, 0xA0), CTRLBUS_OK);
    CHECK_EQ(ctrlbus_base_queue_command(&base, 0xA1), CTRLBUS_ERR_TOO_BIG);
    request_hex("50");
    const uint8_t *p = expect_ok(2);
    if (p != NULL) {
        CHECK_EQ(p[0], 0xA0);
    }
    request_hex("5F");
    expect_ok(0);
    CHECK_EQ(ctrlbus_base_queue_command(&base, 0xA1), CTRLBUS_OK);
    request_hex("50");
    p = expect_ok(2);
    if (p != NULL) {
        CHECK_EQ(p[0], 0xA1);
    }
    expect_nothing_more();
}

/* ---- BASE_CMD ------------------------------------------------------------------------------- */

/* The reset forgets what came before it, not what arrives while the reboot handler runs (a host
 * base's reader thread feeding meanwhile): that is the rebooted base's first input. */
static void test_bytes_fed_while_rebooting_are_heard(void)
{
    static const uint8_t status_request[] = {0x10, 0x02, 0xF8, 0x30, 0xDA};
    setup();
    app.fed_at_reboot = status_request;
    app.fed_at_reboot_len = sizeof status_request;
    feed_hex("10 02 F9 02 E9  10 02 F8 30 DA");
    ctrlbus_base_poll(&base, now);
    CHECK_EQ(app.reboot_calls, 1);
    expect_ok(0);
    expect_nothing_more(); /* the request behind REBOOT in the burst was before the reset */
    ctrlbus_base_poll(&base, now);
    expect_ok(2); /* the one fed during the handler */
    expect_nothing_more();
}

static void test_reboot_answers_first_then_resets(void)
{
    setup();
#if CTRLBUS_CONFIG_HEALTH
    CHECK_EQ(ctrlbus_base_health_add(&base, 5, "app"), 1);
#endif
#if CTRLBUS_CONFIG_COMMAND_QUEUE
    CHECK_EQ(ctrlbus_base_queue_command(&base, 0x90), CTRLBUS_OK);
#endif
    set_motor(10, 10);
    expect_ok(0);
    /* REBOOT, and a request behind it in the same burst: a resetting base does not hear it. */
    feed_hex("10 02 F9 02 E9  10 02 F8 30 DA");
    now += 500;
    ctrlbus_base_poll(&base, now);
    CHECK_EQ(app.reboot_calls, 1);
    CHECK_EQ(app.output_at_reboot, output_len); /* the OK was written before the handler ran */
    CHECK_EQ(app.health_at_reboot, 0);           /* and the session was forgotten */
    CHECK_EQ(app.commands_at_reboot, 0);
    expect_ok(0);
    expect_nothing_more();
    /* Afresh: no health, no commands (nCMD released), watchdog restarted, uptime from now. */
    CHECK_EQ(ctrlbus_base_health_count(&base), 0);
    CHECK_EQ(ctrlbus_base_commands_pending(&base), 0);
    CHECK(!app.line_low);
    now += 1000;
    ctrlbus_base_poll(&base, now);
    CHECK_EQ(app.stop_calls, 0);
    now += 1;
    ctrlbus_base_poll(&base, now);
    CHECK_EQ(app.stop_calls, 1);
    ctrlbus_base_counters_t counters;
    ctrlbus_base_counters(&base, &counters);
    CHECK_EQ(counters.watchdog_trips, 0); /* the rebooted base had not been told to move */
    request_hex("30");
    expect_ok(2);

    /* ENTER_DFU: OK, then the handler; nothing is reset. */
#if CTRLBUS_CONFIG_HEALTH
    CHECK_EQ(ctrlbus_base_health_add(&base, 5, "app"), 1);
#endif
    feed_hex("10 02 F9 01 EA");
    ctrlbus_base_poll(&base, now);
    CHECK_EQ(app.dfu_calls, 1);
    CHECK_EQ(app.output_at_reboot, output_len);
    expect_ok(0);
    CHECK_EQ(ctrlbus_base_health_count(&base), CTRLBUS_CONFIG_HEALTH ? 1 : 0);
    /* Malformed BASE_CMD. */
    feed_hex("10 01 F9 E8  10 03 F9 02 00 E8  10 02 F9 03 E8");
    ctrlbus_base_poll(&base, now);
    expect_error(CTRLBUS_WIRE_ERR_FORMAT);
    expect_error(CTRLBUS_WIRE_ERR_FORMAT);
    expect_error(CTRLBUS_WIRE_ERR_UNSUPPORTED);
    expect_nothing_more();
}

/* ---- features compiled out (ctrlbus/ctrlbus_config.h) --------------------------------------- */

/* What a switch that is off leaves: init refuses a config that asks for the feature, its API
 * fails with CTRLBUS_ERR_UNSUPPORTED, an optional request it served is answered 0x8000, and a
 * mandatory one is answered as by a base with nothing to report. In the default build (every
 * switch on) there is nothing to check here. */
static void test_compiled_out_features_answer_and_fail_clearly(void)
{
    setup();
    ctrlbus_base_config_t asks = full_config();
    (void)asks;
#if !CTRLBUS_CONFIG_HEALTH
    static ctrlbus_base_health_entry_t entries[2];
    asks = full_config();
    asks.health_entries = entries;
    asks.health_capacity = 2;
    CHECK_EQ(ctrlbus_base_init(&base, &asks, now), CTRLBUS_ERR_UNSUPPORTED);
    CHECK(start());
    CHECK_EQ(ctrlbus_base_health_add(&base, 5, "app"), CTRLBUS_ERR_UNSUPPORTED);
    CHECK_EQ(ctrlbus_base_health_clear(&base, 5), CTRLBUS_ERR_UNSUPPORTED);
    CHECK_EQ(ctrlbus_base_health_count(&base), 0);
    request_hex("90 01");
    const uint8_t *health = expect_ok(CTRLBUS_HEALTH_GET_HEALTH_ANSWER_SIZE);
    if (health != NULL) {
        CHECK_EQ(health[0], 0);
        CHECK_EQ(health[1], 0);
    }
    request_hex("90 02 00");
    expect_error(CTRLBUS_WIRE_ERR_OPERATION);
    request_hex("90 03 00 80 03 01");
    expect_error(CTRLBUS_WIRE_ERR_OPERATION);
#endif
#if !CTRLBUS_CONFIG_COMMAND_QUEUE
    static uint8_t queue[2];
    asks = full_config();
    asks.command_queue = queue;
    asks.command_queue_size = 2;
    CHECK_EQ(ctrlbus_base_init(&base, &asks, now), CTRLBUS_ERR_UNSUPPORTED);
    CHECK(start());
    CHECK_EQ(ctrlbus_base_queue_command(&base, 0x90), CTRLBUS_ERR_UNSUPPORTED);
    CHECK_EQ(ctrlbus_base_commands_pending(&base), 0);
    ctrlbus_base_clear_commands(&base);
    CHECK_EQ(app.line_calls, 0);
    request_hex("50");
    expect_ok(0); /* nothing pending, the reference's form */
    request_hex("5F");
    expect_ok(0);
#endif
#if !CTRLBUS_CONFIG_LIMITS
    asks = full_config();
    asks.limits.max_wheel_mm_s = 100;
    CHECK_EQ(ctrlbus_base_init(&base, &asks, now), CTRLBUS_ERR_UNSUPPORTED);
    asks = full_config();
    asks.limits.max_omega_radps_q16 = 65536;
    CHECK_EQ(ctrlbus_base_init(&base, &asks, now), CTRLBUS_ERR_UNSUPPORTED);
    CHECK(start());
    set_motor(5000, -5000); /* passed on unchanged */
    expect_ok(0);
    CHECK_EQ(app.left_mm_s, 5000);
    CHECK_EQ(app.right_mm_s, -5000);
#endif
#if !CTRLBUS_CONFIG_PROFILE_SDK2020
    asks = full_config();
    asks.profile = CTRLBUS_PROFILE_SDK2020;
    CHECK_EQ(ctrlbus_base_init(&base, &asks, now), CTRLBUS_ERR_UNSUPPORTED);
#endif
#if !CTRLBUS_CONFIG_CONF_ADV
    asks = full_config();
    asks.binary_config = BLOB;
    asks.binary_config_size = sizeof BLOB;
    CHECK_EQ(ctrlbus_base_init(&base, &asks, now), CTRLBUS_ERR_UNSUPPORTED);
    CHECK(start());
    request_hex("21");
    expect_error(CTRLBUS_WIRE_ERR_UNSUPPORTED); /* the Core then asks GET_BASE_CONF */
#endif
    expect_nothing_more();
}

/* ---- the receive ring ----------------------------------------------------------------------- */

static void test_ring_overflow_drops_and_counts(void)
{
    setup();
    static uint8_t small_ring[16];
    config.rx_ring = small_ring;
    config.rx_ring_size = sizeof small_ring;
    start();
    uint8_t bytes[40];
    memset(bytes, 0x00, sizeof bytes);
    CHECK_EQ(ctrlbus_base_feed(&base, bytes, sizeof bytes), 15); /* holds size - 1 */
    ctrlbus_base_counters_t counters;
    ctrlbus_base_counters(&base, &counters);
    CHECK_EQ(counters.rx_dropped, 25);
    ctrlbus_base_poll(&base, now);
    expect_error(CTRLBUS_WIRE_ERR_NOT_SYNCHRONISED);
    /* Emptied by the poll: the ring wraps around and a request across the wrap is answered. */
    feed_hex("10 02 F8 30 DA");
    ctrlbus_base_poll(&base, now);
    expect_ok(2);
    for (int i = 0; i < 10; i++) {
        feed_hex("10 03 01 AA 55 ED");
        ctrlbus_base_poll(&base, now);
        answer_t a;
        if (next_answer(&a)) {
            CHECK_EQ(a.cmd, CTRLBUS_CMD_ECHO);
        }
    }
    expect_nothing_more();
}

/* A receive interrupt's byte at a time: the same ring, the same count of dropped bytes. */
static void test_feed_byte_fills_the_ring_and_counts_drops(void)
{
    setup();
    static uint8_t small_ring[8];
    config.rx_ring = small_ring;
    config.rx_ring_size = sizeof small_ring;
    start();
    static const uint8_t request[] = {0x10, 0x02, 0xF8, 0x30, 0xDA};
    for (size_t i = 0; i < sizeof request; i++) {
        CHECK(ctrlbus_base_feed_byte(&base, request[i]));
    }
    ctrlbus_base_poll(&base, now);
    expect_ok(2);
    for (int i = 0; i < 7; i++) {
        CHECK(ctrlbus_base_feed_byte(&base, 0x00)); /* the ring holds size - 1 */
    }
    CHECK(!ctrlbus_base_feed_byte(&base, 0x00));
    CHECK(!ctrlbus_base_feed_byte(&base, 0x00));
    ctrlbus_base_counters_t counters;
    ctrlbus_base_counters(&base, &counters);
    CHECK_EQ(counters.rx_dropped, 2);
    CHECK(!ctrlbus_base_feed_byte(NULL, 0x10));
    ctrlbus_base_poll(&base, now);
    expect_error(CTRLBUS_WIRE_ERR_NOT_SYNCHRONISED);
    expect_nothing_more();
}

/* rx_free() says what feed would take, before and after the ring's indexes wrap: a producer that
 * takes bytes only while it is above 0 never sees one dropped. */
static void test_rx_free_counts_the_room_left(void)
{
    setup();
    static uint8_t small_ring[8];
    config.rx_ring = small_ring;
    config.rx_ring_size = sizeof small_ring;
    start();
    CHECK_EQ(ctrlbus_base_rx_free(&base), 7);
    static const uint8_t request[] = {0x10, 0x02, 0xF8, 0x30, 0xDA};
    for (size_t i = 0; i < sizeof request; i++) {
        CHECK(ctrlbus_base_feed_byte(&base, request[i]));
        CHECK_EQ(ctrlbus_base_rx_free(&base), 6 - i);
    }
    ctrlbus_base_poll(&base, now);
    expect_ok(2);
    CHECK_EQ(ctrlbus_base_rx_free(&base), 7);
    for (size_t i = 0; i < 2 * sizeof request; i++) { /* head wraps past the ring's end */
        if (ctrlbus_base_rx_free(&base) == 0) {
            ctrlbus_base_poll(&base, now);
            expect_ok(2);
            CHECK_EQ(ctrlbus_base_rx_free(&base), 7);
        }
        CHECK(ctrlbus_base_feed_byte(&base, request[i % sizeof request]));
    }
    CHECK_EQ(ctrlbus_base_rx_free(&base), 4); /* 10 bytes: 7 before the poll above, 3 after */
    ctrlbus_base_poll(&base, now);
    expect_ok(2);
    expect_nothing_more();
    ctrlbus_base_counters_t counters;
    ctrlbus_base_counters(&base, &counters);
    CHECK_EQ(counters.rx_dropped, 0);
    CHECK_EQ(ctrlbus_base_rx_free(NULL), 0);
}

/* The stream an "interrupt" plays into the base: requests of every shape, answers predictable. */
#define STREAM_REQUESTS 3000
static uint8_t stream[STREAM_REQUESTS * 40];
static size_t stream_len;
static size_t stream_sent;
static uint8_t expected_answers[STREAM_REQUESTS * 60];
static size_t expected_len;

static void append_request(uint8_t cmd, const uint8_t *payload, size_t len, bool is_long)
{
    int32_t size = ctrlbus_frame_encode(stream + stream_len, sizeof stream - stream_len, cmd,
                                        payload, len,
                                        is_long ? CTRLBUS_FRAME_LONG : CTRLBUS_FRAME_STANDARD);
    if (size < 0) {
        harness_fail(__FILE__, __LINE__, "stream buffer full");
        return;
    }
    if (cmd <= CTRLBUS_CMD_ECHO) {
        memcpy(expected_answers + expected_len, stream + stream_len, (size_t)size);
        expected_len += (size_t)size;
    }
    stream_len += (size_t)size;
}

static void build_stream(void)
{
    stream_len = expected_len = 0;
    for (uint32_t i = 0; i < STREAM_REQUESTS; i++) {
        uint8_t payload[32];
        switch (i % 4) {
        case 0: { /* ECHO of varying size and content */
            size_t len = i % 29;
            for (size_t k = 0; k < len; k++) {
                payload[k] = (uint8_t)(i + k * 31u);
            }
            append_request(CTRLBUS_CMD_ECHO, payload, len, (i & 8u) != 0);
            break;
        }
        case 1: { /* GET_BASE_STATUS: OK 80 % / 3 */
            payload[0] = CTRLBUS_CODE_GET_BASE_STATUS;
            append_request(CTRLBUS_CMD_CTRL_BUS, payload, 1, false);
            static const uint8_t OK_STATUS[] = {0x50, 0x03, 0x00, 0x02, 80, 3,
                                                0x50 ^ 0x03 ^ 0x02 ^ 80 ^ 3};
            memcpy(expected_answers + expected_len, OK_STATUS, sizeof OK_STATUS);
            expected_len += sizeof OK_STATUS;
            break;
        }
        case 2: { /* SET_BASE_MOTOR: empty OK */
            memset(payload, 0, 17);
            payload[0] = CTRLBUS_CODE_SET_BASE_MOTOR;
            payload[1] = (uint8_t)i;
            append_request(CTRLBUS_CMD_CTRL_BUS, payload, 17, true);
            static const uint8_t OK_EMPTY[] = {0x50, 0x01, 0x00, 0x02, 0x53};
            memcpy(expected_answers + expected_len, OK_EMPTY, sizeof OK_EMPTY);
            expected_len += sizeof OK_EMPTY;
            break;
        }
        default: { /* SYNC with filler */
            size_t len = (i / 4) % 13;
            memset(payload, 0x55, len);
            append_request(CTRLBUS_CMD_SYNC, payload, len, false);
            break;
        }
        }
    }
}

/* A simulated interrupt: delivers the next few bytes of the stream whenever it fires. */
static void interrupt_delivers_bytes(void)
{
    static uint32_t fired;
    size_t burst = 1u + (fired++ % 5u);
    if (burst > stream_len - stream_sent) {
        burst = stream_len - stream_sent;
    }
    stream_sent += ctrlbus_base_feed(&base, stream + stream_sent, burst);
}

static void test_interrupt_feeding_inside_the_poll_loses_nothing(void)
{
    /* The interrupt fires inside every write of every answer (the middle of the poll loop),
     * and between polls; the small ring fills up and the "UART" holds the rest back. */
    setup();
    static uint8_t small_ring[64];
    config.rx_ring = small_ring;
    config.rx_ring_size = sizeof small_ring;
    start();
    build_stream();
    stream_sent = 0;
    on_write = interrupt_delivers_bytes;
    for (int polls = 0;
         polls < 1000000 && (stream_sent < stream_len || output_len < expected_len); polls++) {
        interrupt_delivers_bytes();
        now += 1;
        ctrlbus_base_poll(&base, now);
    }
    on_write = NULL;
    CHECK_EQ(stream_sent, stream_len);
    CHECK_MEM(output, output_len, expected_answers, expected_len);
    CHECK_EQ(app.wheel_calls, STREAM_REQUESTS / 4);
    CHECK_EQ(decoder_stats.bytes_discarded, 0);
    CHECK_EQ(decoder_stats.frames, STREAM_REQUESTS);
}

/* A real second thread as the interrupt: it pushes the stream as fast as the ring takes it,
 * while the main thread polls. Run under ASan in the sanitized build. */
static volatile int producer_done;

static void *producer_thread(void *unused)
{
    (void)unused;
    size_t sent = 0;
    while (sent < stream_len) {
        size_t burst = stream_len - sent < 23 ? stream_len - sent : 23;
        size_t taken = ctrlbus_base_feed(&base, stream + sent, burst);
        sent += taken;
        if (taken < burst) {
            struct timespec pause = {0, 20000};
            nanosleep(&pause, NULL); /* a UART holds the rest back while the ring is full */
        }
    }
    producer_done = 1;
    return NULL;
}

static void test_thread_feeding_while_polling_loses_nothing(void)
{
    setup();
    static uint8_t ring[256];
    config.rx_ring = ring;
    config.rx_ring_size = sizeof ring;
    config.frame_timeout_ms = CTRLBUS_BASE_TIMEOUT_OFF; /* the fake clock is not wall time */
    start();
    build_stream();
    producer_done = 0;
    pthread_t producer;
    if (!CHECK_EQ(pthread_create(&producer, NULL, producer_thread, NULL), 0)) {
        return;
    }
    /* Bounded: the test fails instead of hanging if bytes were lost. */
    for (long polls = 0; polls < 20000000L && output_len < expected_len; polls++) {
        ctrlbus_base_poll(&base, now);
        now += (polls & 63) == 0 ? 1u : 0u;
    }
    pthread_join(producer, NULL);
    CHECK(producer_done);
    ctrlbus_base_poll(&base, now);
    CHECK_MEM(output, output_len, expected_answers, expected_len);
    CHECK_EQ(decoder_stats.bytes_discarded, 0);
    CHECK_EQ(decoder_stats.frames, STREAM_REQUESTS);
}

/* ---- the shared vectors --------------------------------------------------------------------- */

/* The vectors' timeout_ms (0: off) as the stack's frame_timeout_ms. */
static uint16_t frame_timeout(uint32_t timeout_ms)
{
    return timeout_ms != 0 ? (uint16_t)timeout_ms : CTRLBUS_BASE_TIMEOUT_OFF;
}

static void test_invalid_json_base_answers(void)
{
    size_t checked = 0;
    for (size_t i = 0; i < VEC_FRAME_LEVEL_COUNT; i++) {
        const vec_frame_level_t *v = &VEC_FRAME_LEVEL[i];
        if (!v->has_base_answer) {
            continue;
        }
        harness_context("invalid.json frame_level %s", v->name);
        setup();
        config.frame_buffer_size = v->max_frame;
        config.frame_timeout_ms = frame_timeout(v->timeout_ms);
        start();
        feed(v->input.data, v->input.len);
        ctrlbus_base_poll(&base, now);
        if (v->timeout_ms != 0) {
            now += v->timeout_ms + 1u; /* an idle gap past the timeout */
            ctrlbus_base_poll(&base, now);
        }
        CHECK_MEM(output, output_len, v->base_answer.data, v->base_answer.len);
        /* Nothing the vectors feed may reach the motors. */
        CHECK_EQ(app.wheel_calls + app.velocity_calls, 0);
        checked++;
    }
    for (size_t i = 0; i < VEC_MESSAGE_LEVEL_COUNT; i++) {
        const vec_message_level_t *v = &VEC_MESSAGE_LEVEL[i];
        if (!v->has_base_answer) {
            continue;
        }
        harness_context("invalid.json message_level %s", v->name);
        setup();
        send_frame(v->cmd, v->payload.data, v->payload.len, v->is_long);
        CHECK_MEM(output, output_len, v->base_answer.data, v->base_answer.len);
        CHECK_EQ(app.wheel_calls + app.velocity_calls + app.reboot_calls + app.dfu_calls, 0);
        checked++;
    }
    harness_context(NULL);
    if (checked == 0) {
        harness_note("invalid.json: no base_answer cases (file absent or empty)");
    }
}

static void test_streams_json_one_answer_per_frame_and_event(void)
{
    /* Every stream vector through the base: each frame it yields is answered once, each event
     * per §8.1 (every event but timeout gets one ERROR), in stream order. */
    for (size_t i = 0; i < VEC_STREAMS_COUNT; i++) {
        const vec_stream_t *v = &VEC_STREAMS[i];
        harness_context("streams.json %s", v->name);
        setup();
        config.frame_buffer_size = v->max_frame;
        config.frame_timeout_ms = frame_timeout(v->timeout_ms);
        config.watchdog_ms = CTRLBUS_BASE_WATCHDOG_OFF;
        now = 0;
        start();
        uint32_t last = 0;
        for (size_t c = 0; c < v->chunk_count; c++) {
            now = v->chunks[c].t_ms;
            ctrlbus_base_poll(&base, now); /* time moves on before the chunk's bytes */
            feed(v->chunks[c].data.data, v->chunks[c].data.len);
            ctrlbus_base_poll(&base, now);
            last = now;
        }
        if (v->has_final_idle) {
            now = last + v->final_idle_ms;
            ctrlbus_base_poll(&base, now);
        }
        size_t answers = 0;
        answer_t a;
        while (output_read < output_len && next_answer(&a)) {
            answers++;
        }
        size_t expected = v->expect.frame_count;
        for (size_t e = 0; e < v->expect.event_count; e++) {
            expected += strcmp(v->expect.events[e], "timeout") != 0 ? 1u : 0u;
        }
        if (v->expect.events_given) {
            CHECK_EQ(answers, expected);
        }
    }
    harness_context(NULL);
    (void)VEC_FRAMES;
    (void)VEC_FRAMES_COUNT;
}

int main(void)
{
    RUN(test_init_refuses_bad_configurations);
    RUN(test_sync_and_echo_are_copied_verbatim);
    RUN(test_connect_base);
    RUN(test_get_base_conf_is_a_long_frame);
    if (CTRLBUS_CONFIG_CONF_ADV) {
        RUN(test_binary_config_is_streamed_from_the_callers_array);
    }
    RUN(test_telemetry_requests);
    RUN(test_motion_requests);
    RUN(test_events);
    RUN(test_unimplemented_requests_are_answered_unsupported);
    RUN(test_handler_failures);
    RUN(test_checksum_failed_set_base_motor_is_not_executed);
    RUN(test_decoder_events);
    RUN(test_frame_timeout_is_configurable);
    RUN(test_reset_line_forgets_the_half_frame);
    RUN(test_answer_frame_types);
    RUN(test_answers_keep_stream_order);
    RUN(test_a_failing_write_cuts_one_answer_only);
    if (CTRLBUS_CONFIG_PROFILE_SDK2020) {
        RUN(test_sdk2020_profile);
    }
    RUN(test_watchdog_trips_after_1000_ms_and_shows_in_health);
    RUN(test_watchdog_idle_expiry_and_what_feeds_it);
    RUN(test_watchdog_period_and_off);
    RUN(test_watchdog_across_clock_wrap);
    if (CTRLBUS_CONFIG_LIMITS) {
        RUN(test_wheel_limit_scales_both_wheels);
    }
    if (CTRLBUS_CONFIG_LIMITS) {
        RUN(test_velocity_limits);
    }
    if (CTRLBUS_CONFIG_HEALTH) {
        RUN(test_health_registry);
    }
    if (CTRLBUS_CONFIG_HEALTH) {
        RUN(test_health_without_storage_holds_the_watchdog_warning);
    }
    if (CTRLBUS_CONFIG_HEALTH) {
        RUN(test_full_health_registry_does_not_stop_the_watchdog);
    }
    if (CTRLBUS_CONFIG_COMMAND_QUEUE) {
        RUN(test_external_command_queue);
    }
    if (CTRLBUS_CONFIG_COMMAND_QUEUE) {
        RUN(test_command_queue_without_storage_holds_one);
    }
    RUN(test_reboot_answers_first_then_resets);
    RUN(test_bytes_fed_while_rebooting_are_heard);
    RUN(test_compiled_out_features_answer_and_fail_clearly);
    RUN(test_ring_overflow_drops_and_counts);
    RUN(test_feed_byte_fills_the_ring_and_counts_drops);
    RUN(test_rx_free_counts_the_room_left);
    RUN(test_interrupt_feeding_inside_the_poll_loses_nothing);
    RUN(test_thread_feeding_while_polling_loses_nothing);
    RUN(test_invalid_json_base_answers);
    RUN(test_streams_json_one_answer_per_frame_and_event);
    return harness_finish();
}
