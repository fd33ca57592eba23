/* SPDX-License-Identifier: MIT */
/* Unit tests of the message layer: every request and answer round trip, the reference's example
 * frames, wrong lengths, and the errors a base answers with. */
#include <string.h>

#include "ctrlbus/messages.h"
#include "answer_fields.h"
#include "harness.h"
#include "msg_fields.h"

static uint8_t decoder_buffer[CTRLBUS_FRAME_MAX];
static msg_fields_t fields_a;
static msg_fields_t fields_b;

/* Runs wire bytes through a stream decoder: true when they are exactly one frame. */
static bool decode_wire(const uint8_t *wire, size_t len, ctrlbus_frame_t *frame)
{
    static ctrlbus_decoder_t decoder;
    ctrlbus_decoder_init(&decoder, decoder_buffer, sizeof decoder_buffer, 0, NULL);
    if (ctrlbus_decoder_feed(&decoder, wire, len, 0) != len) {
        return false;
    }
    if (ctrlbus_decoder_next(&decoder, frame) != CTRLBUS_RX_FRAME) {
        return false;
    }
    return ctrlbus_decoder_next(&decoder, NULL) == CTRLBUS_RX_NONE &&
           !ctrlbus_decoder_busy(&decoder);
}

static const ctrlbus_frame_type_t BOTH_TYPES[] = {CTRLBUS_FRAME_STANDARD, CTRLBUS_FRAME_LONG};

static void roundtrip_request(const ctrlbus_request_t *request)
{
    static uint8_t wire[CTRLBUS_FRAME_MAX];
    static uint8_t again[CTRLBUS_FRAME_MAX];
    harness_context("request %s", ctrlbus_request_name(request->kind));
    int32_t payload_size = ctrlbus_request_payload_size(request);
    CHECK(payload_size >= 0);
    for (size_t t = 0; t < 2; t++) {
        int32_t len = ctrlbus_request_encode(wire, sizeof wire, request, BOTH_TYPES[t]);
        if (!CHECK_EQ(len, ctrlbus_frame_size((size_t)payload_size, BOTH_TYPES[t]))) {
            continue;
        }
        ctrlbus_frame_t frame;
        if (!CHECK(decode_wire(wire, (size_t)len, &frame))) {
            continue;
        }
        CHECK_EQ(frame.is_long, BOTH_TYPES[t] == CTRLBUS_FRAME_LONG);
        CHECK_EQ(frame.cmd, ctrlbus_request_cmd(request->kind));
        ctrlbus_request_t decoded;
        CHECK_EQ(ctrlbus_request_decode(&decoded, frame.cmd, frame.payload, frame.payload_len),
                 CTRLBUS_OK);
        CHECK_EQ(decoded.kind, request->kind);
        msg_fields_of_request(&fields_a, request);
        msg_fields_of_request(&fields_b, &decoded);
        CHECK(msg_fields_equal(&fields_a, &fields_b));
        /* Encoding the decoded request gives the same bytes. */
        CHECK_EQ(ctrlbus_request_encode(again, sizeof again, &decoded, BOTH_TYPES[t]), len);
        CHECK_MEM(again, (size_t)len, wire, (size_t)len);
    }
    harness_context(NULL);
}

/* Writes an OK answer through its layout's own writer (ctrlbus_<name>_answer_write, what the
 * base stack uses) into out; returns what the writer returned. *written gets the bytes that
 * reached the buffer. */
static int32_t layout_write(const ctrlbus_answer_t *a, uint8_t *out, size_t size,
                            ctrlbus_frame_type_t type, size_t *written)
{
    ctrlbus_sink_t sink;
    ctrlbus_buffer_t buffer;
    ctrlbus_sink_init_buffer(&sink, &buffer, out, size);
    int32_t result;
    switch (a->to) {
    case CTRLBUS_REQ_CONNECT_BASE:
        result = ctrlbus_connect_base_answer_write(&sink, &a->as.connect_base, type);
        break;
    case CTRLBUS_REQ_GET_BASE_CONF:
        result = ctrlbus_get_base_conf_answer_write(&sink, &a->as.get_base_conf, type);
        break;
    case CTRLBUS_REQ_GET_BASE_CONF_ADV:
        result = ctrlbus_get_base_conf_adv_answer_write(&sink, &a->as.get_base_conf_adv, type);
        break;
    case CTRLBUS_REQ_GET_BASE_STATUS:
        result = ctrlbus_get_base_status_answer_write(&sink, &a->as.get_base_status, type);
        break;
    case CTRLBUS_REQ_GET_BASE_MOTOR_DATA:
        result = ctrlbus_get_base_motor_data_answer_write(&sink, &a->as.get_base_motor_data, type);
        break;
    case CTRLBUS_REQ_GET_BASE_SENSOR_DATA:
        result =
            ctrlbus_get_base_sensor_data_answer_write(&sink, &a->as.get_base_sensor_data, type);
        break;
    case CTRLBUS_REQ_GET_BASE_BUMPER_DATA:
        result =
            ctrlbus_get_base_bumper_data_answer_write(&sink, &a->as.get_base_bumper_data, type);
        break;
    case CTRLBUS_REQ_GET_CHARGER_DATA:
        result = ctrlbus_get_charger_data_answer_write(&sink, &a->as.get_charger_data, type);
        break;
    case CTRLBUS_REQ_SET_V_AND_GET_DEADRECKON:
        result = ctrlbus_set_v_and_get_deadreckon_answer_write(
            &sink, &a->as.set_v_and_get_deadreckon, type);
        break;
    case CTRLBUS_REQ_POLL_BASE_CMD:
        result = ctrlbus_poll_base_cmd_answer_write(&sink, &a->as.poll_base_cmd, type);
        break;
    case CTRLBUS_REQ_HEALTH_GET_HEALTH:
        result = ctrlbus_health_get_health_answer_write(&sink, &a->as.health_get_health, type);
        break;
    case CTRLBUS_REQ_HEALTH_GET_ERROR:
        result = ctrlbus_health_get_error_answer_write(&sink, &a->as.health_get_error, type);
        break;
    default: result = ctrlbus_ok_answer_write(&sink, type); break; /* the empty OK answers */
    }
    *written = buffer.len;
    return result;
}

static void roundtrip_answer(const ctrlbus_answer_t *answer)
{
    static uint8_t wire[CTRLBUS_FRAME_MAX];
    static uint8_t again[CTRLBUS_FRAME_MAX];
    harness_context("answer %s to %s", ctrlbus_answer_name(answer->kind),
                    ctrlbus_request_name(answer->to));
    int32_t payload_size = ctrlbus_answer_payload_size(answer);
    CHECK(payload_size >= 0);
    for (size_t t = 0; t < 2; t++) {
        if (payload_size > (int32_t)CTRLBUS_STANDARD_PAYLOAD_MAX &&
            BOTH_TYPES[t] == CTRLBUS_FRAME_STANDARD) {
            CHECK_EQ(ctrlbus_answer_encode(wire, sizeof wire, answer, BOTH_TYPES[t]),
                     CTRLBUS_ERR_TOO_BIG);
            continue;
        }
        int32_t len = ctrlbus_answer_encode(wire, sizeof wire, answer, BOTH_TYPES[t]);
        if (!CHECK_EQ(len, ctrlbus_frame_size((size_t)payload_size, BOTH_TYPES[t]))) {
            continue;
        }
        ctrlbus_frame_t frame;
        if (!CHECK(decode_wire(wire, (size_t)len, &frame))) {
            continue;
        }
        ctrlbus_answer_t decoded;
        CHECK_EQ(ctrlbus_answer_decode(&decoded, answer->to, frame.cmd, frame.payload,
                                       frame.payload_len),
                 CTRLBUS_OK);
        CHECK_EQ(decoded.kind, answer->kind);
        msg_fields_of_answer(&fields_a, answer);
        msg_fields_of_answer(&fields_b, &decoded);
        CHECK(msg_fields_equal(&fields_a, &fields_b));
        CHECK_EQ(ctrlbus_answer_encode(again, sizeof again, &decoded, BOTH_TYPES[t]), len);
        CHECK_MEM(again, (size_t)len, wire, (size_t)len);
        if (answer->kind == CTRLBUS_ANSWER_OK) {
            /* The layout's own writer gives the same frame as the union's. */
            size_t written = 0;
            CHECK_EQ(layout_write(answer, again, sizeof again, BOTH_TYPES[t], &written), len);
            CHECK_MEM(again, written, wire, (size_t)len);
        }
    }
    harness_context(NULL);
}

static ctrlbus_request_t request_of(ctrlbus_req_kind_t kind)
{
    ctrlbus_request_t r;
    memset(&r, 0, sizeof r);
    r.kind = kind;
    return r;
}

static ctrlbus_answer_t ok_to(ctrlbus_req_kind_t to)
{
    ctrlbus_answer_t a;
    memset(&a, 0, sizeof a);
    a.kind = CTRLBUS_ANSWER_OK;
    a.to = to;
    return a;
}

/* ---- round trips ---------------------------------------------------------------------------- */

static void test_every_request_round_trips(void)
{
    static const uint8_t filler[300] = {0x10, 0x50, 0x00, 0xFF};
    ctrlbus_request_t r;
    for (int kind = CTRLBUS_REQ_SYNC; kind < CTRLBUS_REQ_HEALTH_UNKNOWN; kind++) {
        r = request_of((ctrlbus_req_kind_t)kind);
        switch (r.kind) {
        case CTRLBUS_REQ_SYNC:
            r.as.sync.filler = filler;
            r.as.sync.filler_len = 200;
            break;
        case CTRLBUS_REQ_ECHO:
            r.as.echo.data = filler;
            r.as.echo.data_len = 3;
            break;
        case CTRLBUS_REQ_BASE_CMD: r.as.base_cmd.subcommand = CTRLBUS_BASE_CMD_REBOOT; break;
        case CTRLBUS_REQ_CONNECT_BASE: r.as.connect_base.protocol_version = 1; break;
        case CTRLBUS_REQ_GET_CHARGER_DATA: r.as.get_charger_data.data_type = 0; break;
        case CTRLBUS_REQ_SET_BASE_MOTOR:
            r.as.set_base_motor.speeds_mm_s[0] = -150;
            r.as.set_base_motor.speeds_mm_s[1] = 2147483647;
            r.as.set_base_motor.speeds_mm_s[2] = -2147483647 - 1;
            r.as.set_base_motor.speeds_mm_s[3] = 7;
            break;
        case CTRLBUS_REQ_SET_V_AND_GET_DEADRECKON:
            r.as.set_v_and_get_deadreckon.vx_mps_q16 = 13107;
            r.as.set_v_and_get_deadreckon.vy_mps_q16 = -1;
            r.as.set_v_and_get_deadreckon.omega_radps_q16 = -32768;
            break;
        case CTRLBUS_REQ_SEND_EVENT: r.as.send_event.event = 0x63; break;
        case CTRLBUS_REQ_HEALTH_GET_ERROR: r.as.health_get_error.index = 4; break;
        case CTRLBUS_REQ_HEALTH_CLR_ERROR: r.as.health_clr_error.error_code = 0x01020100u; break;
        default: break;
        }
        roundtrip_request(&r);
    }
    /* A SYNC with filler longer than a standard frame goes as a long frame. */
    r = request_of(CTRLBUS_REQ_SYNC);
    r.as.sync.filler = filler;
    r.as.sync.filler_len = sizeof filler;
    static uint8_t wire[400];
    CHECK_EQ(ctrlbus_request_encode(wire, sizeof wire, &r, CTRLBUS_FRAME_AUTO), 305);
    CHECK_EQ(wire[0], CTRLBUS_FLAG_LONG);
}

static void fill_position(ctrlbus_position_t *p, int32_t seed)
{
    p->x_mm_q8 = seed * 256;
    p->y_mm_q8 = -seed * 300;
    p->z_mm_q8 = seed;
    p->angle_deg_q8 = (uint32_t)(315 * 256 + seed);
}

static void test_every_answer_round_trips(void)
{
    ctrlbus_answer_t a;

    a = ok_to(CTRLBUS_REQ_CONNECT_BASE);
    strcpy(a.as.connect_base.model, "ref base");
    a.as.connect_base.firmware_version = 0x0114;
    a.as.connect_base.hardware_version = 0x0203;
    a.as.connect_base.serial[0] = 0xDEADBEEFu;
    a.as.connect_base.serial[1] = 1;
    a.as.connect_base.serial[2] = 0xFFFFFFFFu;
    roundtrip_answer(&a); /* 28-byte form */
    a.as.connect_base.has_firmware_version_suffix = true;
    strcpy(a.as.connect_base.firmware_version_suffix, "-rc1");
    roundtrip_answer(&a); /* 39-byte form */
    strcpy(a.as.connect_base.model, "ABCDEFGHIJKL"); /* fills the field: no NUL on the wire */
    strcpy(a.as.connect_base.firmware_version_suffix, "12345678901");
    roundtrip_answer(&a);

    a = ok_to(CTRLBUS_REQ_GET_BASE_CONF);
    a.as.get_base_conf.base_type = 1;
    a.as.get_base_conf.base_radius_mm_q8 = 175u * 256u;
    a.as.get_base_conf.motor_type = 0;
    a.as.get_base_conf.sensor_num = 8;
    a.as.get_base_conf.bumper_num = 2;
    for (int32_t i = 0; i < (int32_t)CTRLBUS_CONF_SLOTS; i++) {
        fill_position(&a.as.get_base_conf.sensors[i], i + 1);
        fill_position(&a.as.get_base_conf.bumpers[i], 100 + i);
    }
    roundtrip_answer(&a); /* 264 bytes: only as a long frame */

    static const uint8_t blob[321] = {0x50, 0x03, 0x00};
    a = ok_to(CTRLBUS_REQ_GET_BASE_CONF_ADV);
    a.as.get_base_conf_adv.blob = blob;
    a.as.get_base_conf_adv.blob_len = sizeof blob;
    roundtrip_answer(&a);
    a.as.get_base_conf_adv.blob_len = 0;
    roundtrip_answer(&a);

    a = ok_to(CTRLBUS_REQ_GET_BASE_STATUS);
    a.as.get_base_status.battery_percent = 80;
    a.as.get_base_status.power_status = 3;
    roundtrip_answer(&a);

    a = ok_to(CTRLBUS_REQ_GET_BASE_MOTOR_DATA);
    a.as.get_base_motor_data.left_distance_mm = -123456;
    a.as.get_base_motor_data.right_distance_mm = 654321;
    a.as.get_base_motor_data.status = CTRLBUS_MOTOR_STALL;
    roundtrip_answer(&a);

    a = ok_to(CTRLBUS_REQ_GET_BASE_SENSOR_DATA);
    for (uint32_t i = 0; i < CTRLBUS_SENSOR_CHANNELS; i++) {
        a.as.get_base_sensor_data.distances_mm_q16[i] = i * 0x01010101u;
    }
    roundtrip_answer(&a);

    a = ok_to(CTRLBUS_REQ_GET_BASE_BUMPER_DATA);
    a.as.get_base_bumper_data.bitmap = 0xFFFFFFFCu;
    a.as.get_base_bumper_data.payload_size = 4;
    roundtrip_answer(&a);
    a.as.get_base_bumper_data.bitmap = 0xFE;
    a.as.get_base_bumper_data.payload_size = 1; /* the 2018 form */
    roundtrip_answer(&a);
    a.as.get_base_bumper_data.bitmap = 0xFEDCBAu;
    a.as.get_base_bumper_data.payload_size = 3;
    roundtrip_answer(&a);

    static const uint8_t probes[3] = {0x01, 0x07, 0x04};
    a = ok_to(CTRLBUS_REQ_GET_CHARGER_DATA);
    a.as.get_charger_data.beacon_count = 3;
    a.as.get_charger_data.probe_count = 3;
    a.as.get_charger_data.probes = probes;
    roundtrip_answer(&a);
    a.as.get_charger_data.probe_count = 0;
    a.as.get_charger_data.probes = NULL;
    roundtrip_answer(&a);

    a = ok_to(CTRLBUS_REQ_SET_V_AND_GET_DEADRECKON);
    a.as.set_v_and_get_deadreckon.dx_mm_q16 = 65536 * 12;
    a.as.set_v_and_get_deadreckon.dy_mm_q16 = -5;
    a.as.set_v_and_get_deadreckon.dtheta_deg_q16 = -65536 * 3;
    a.as.set_v_and_get_deadreckon.status = CTRLBUS_MOTOR_TRACTION_LOST;
    roundtrip_answer(&a); /* 13-byte form */
    a.as.set_v_and_get_deadreckon.has_timestamp_ms = true;
    a.as.set_v_and_get_deadreckon.timestamp_ms = 0xFEDCBA98u;
    roundtrip_answer(&a); /* 17-byte form */

    a = ok_to(CTRLBUS_REQ_POLL_BASE_CMD);
    roundtrip_answer(&a); /* nothing pending, empty */
    a.as.poll_base_cmd.payload_size = 2;
    a.as.poll_base_cmd.pad = 0x5A;
    roundtrip_answer(&a); /* nothing pending, 0xFF form */
    a.as.poll_base_cmd.has_command = true;
    a.as.poll_base_cmd.command = 0xA4;
    roundtrip_answer(&a); /* a command */

    a = ok_to(CTRLBUS_REQ_HEALTH_GET_HEALTH);
    a.as.health_get_health.flags = CTRLBUS_HEALTH_WARNING | CTRLBUS_HEALTH_ERROR;
    a.as.health_get_health.error_count = 2;
    roundtrip_answer(&a);

    a = ok_to(CTRLBUS_REQ_HEALTH_GET_ERROR);
    a.as.health_get_error.error_code = CTRLBUS_HEALTH_CODE(1, 2, 1, 0);
    strcpy(a.as.health_get_error.message, "battery low");
    roundtrip_answer(&a);
    strcpy(a.as.health_get_error.message, "0123456789012345678901234567890"); /* 31: the most */
    roundtrip_answer(&a);

    static const ctrlbus_req_kind_t empty_ok[] = {
        CTRLBUS_REQ_SET_BASE_MOTOR, CTRLBUS_REQ_POLL_BASE_ANS_CMD, CTRLBUS_REQ_SEND_EVENT,
        CTRLBUS_REQ_HEALTH_CLR_ERROR, CTRLBUS_REQ_BASE_CMD};
    for (size_t i = 0; i < sizeof empty_ok / sizeof empty_ok[0]; i++) {
        a = ok_to(empty_ok[i]);
        roundtrip_answer(&a);
    }

    a = ok_to(CTRLBUS_REQ_GET_BASE_STATUS);
    a.kind = CTRLBUS_ANSWER_ERROR;
    a.as.error.error_code = CTRLBUS_WIRE_ERR_OPERATION;
    roundtrip_answer(&a);
    a.kind = CTRLBUS_ANSWER_INVALID;
    roundtrip_answer(&a);

    static const uint8_t copy[5] = {1, 2, 3, 4, 5};
    a = ok_to(CTRLBUS_REQ_SYNC);
    a.kind = CTRLBUS_ANSWER_SYNC;
    a.as.sync.filler = copy;
    a.as.sync.filler_len = sizeof copy;
    roundtrip_answer(&a);
    a = ok_to(CTRLBUS_REQ_ECHO);
    a.kind = CTRLBUS_ANSWER_ECHO;
    a.as.echo.data = copy;
    a.as.echo.data_len = 2;
    roundtrip_answer(&a);
}

/* ---- the reference's example frames --------------------------------------------------------- */

static void check_request_wire(const ctrlbus_request_t *r, ctrlbus_frame_type_t type,
                               const char *hex)
{
    uint8_t expected[64];
    uint8_t out[64];
    size_t expected_len = harness_unhex(expected, sizeof expected, hex);
    int32_t len = ctrlbus_request_encode(out, sizeof out, r, type);
    CHECK_EQ(len, (int32_t)expected_len);
    CHECK_MEM(out, len > 0 ? (size_t)len : 0, expected, expected_len);
}

static void check_answer_wire(const ctrlbus_answer_t *a, const char *hex)
{
    uint8_t expected[64];
    uint8_t out[64];
    size_t expected_len = harness_unhex(expected, sizeof expected, hex);
    int32_t len = ctrlbus_answer_encode(out, sizeof out, a, CTRLBUS_FRAME_LONG);
    CHECK_EQ(len, (int32_t)expected_len);
    CHECK_MEM(out, len > 0 ? (size_t)len : 0, expected, expected_len);
}

static void test_reference_example_frames(void)
{
    ctrlbus_request_t r = request_of(CTRLBUS_REQ_SYNC);
    check_request_wire(&r, CTRLBUS_FRAME_AUTO, "10 01 00 11");
    static const uint8_t aa55[2] = {0xAA, 0x55};
    r = request_of(CTRLBUS_REQ_ECHO);
    r.as.echo.data = aa55;
    r.as.echo.data_len = 2;
    check_request_wire(&r, CTRLBUS_FRAME_AUTO, "10 03 01 AA 55 ED");
    check_request_wire(&r, CTRLBUS_FRAME_LONG, "50 03 00 01 AA 55 AD");
    r = request_of(CTRLBUS_REQ_CONNECT_BASE);
    r.as.connect_base.protocol_version = CTRLBUS_PROTOCOL_VERSION;
    check_request_wire(&r, CTRLBUS_FRAME_AUTO, "10 03 F8 10 01 FA");
    r = request_of(CTRLBUS_REQ_GET_BASE_STATUS);
    check_request_wire(&r, CTRLBUS_FRAME_AUTO, "10 02 F8 30 DA");
    check_request_wire(&r, CTRLBUS_FRAME_LONG, "50 02 00 F8 30 9A");
    r = request_of(CTRLBUS_REQ_SET_V_AND_GET_DEADRECKON);
    r.as.set_v_and_get_deadreckon.vx_mps_q16 = 13107;     /* 0.2 m/s */
    r.as.set_v_and_get_deadreckon.omega_radps_q16 = 32768; /* 0.5 rad/s */
    check_request_wire(&r, CTRLBUS_FRAME_AUTO,
                       "10 0E F8 41 33 33 00 00 00 00 00 00 00 80 00 00 27");

    ctrlbus_answer_t a = ok_to(CTRLBUS_REQ_SET_BASE_MOTOR);
    check_answer_wire(&a, "50 01 00 02 53");
    a = ok_to(CTRLBUS_REQ_GET_BASE_STATUS);
    a.as.get_base_status.battery_percent = 80;
    a.as.get_base_status.power_status = CTRLBUS_POWER_CHARGING | CTRLBUS_POWER_DC_CONNECTED;
    check_answer_wire(&a, "50 03 00 02 50 03 02");
    a = ok_to(CTRLBUS_REQ_POLL_BASE_CMD);
    a.as.poll_base_cmd.payload_size = 2;
    check_answer_wire(&a, "50 03 00 02 FF 00 AE");
    a = ok_to(CTRLBUS_REQ_HEALTH_GET_HEALTH);
    check_answer_wire(&a, "50 03 00 02 00 00 51");

    uint8_t out[16];
    uint8_t expected[16];
    ctrlbus_sink_t sink;
    ctrlbus_buffer_t buffer;
    ctrlbus_sink_init_buffer(&sink, &buffer, out, sizeof out);
    CHECK_EQ(ctrlbus_error_answer_write(&sink, CTRLBUS_WIRE_ERR_UNSUPPORTED, CTRLBUS_FRAME_LONG),
             7);
    CHECK_MEM(out, buffer.len, expected, harness_unhex(expected, 16, "50 03 00 03 00 80 D0"));
    ctrlbus_sink_init_buffer(&sink, &buffer, out, sizeof out);
    CHECK_EQ(ctrlbus_error_answer_write(&sink, CTRLBUS_WIRE_ERR_TOO_LONG, CTRLBUS_FRAME_LONG), 7);
    CHECK_MEM(out, buffer.len, expected, harness_unhex(expected, 16, "50 03 00 03 20 00 70"));

    /* And the other way: the example answers decode to what they mean. */
    ctrlbus_answer_t d;
    uint8_t payload[2] = {0xFF, 0x00};
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_POLL_BASE_CMD, CTRLBUS_CMD_OK, payload, 2),
             CTRLBUS_OK);
    CHECK(!d.as.poll_base_cmd.has_command);
    CHECK_EQ(d.as.poll_base_cmd.payload_size, 2);
    CHECK_EQ(d.as.poll_base_cmd.pad, 0);
    payload[0] = 0x00;
    payload[1] = 0x80;
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_GET_BASE_STATUS, CTRLBUS_CMD_ERROR, payload, 2),
             CTRLBUS_OK);
    CHECK_EQ(d.kind, CTRLBUS_ANSWER_ERROR);
    CHECK_EQ(d.as.error.error_code, 0x8000);
}

/* ---- wrong lengths and unknown requests ----------------------------------------------------- */

static void test_request_wrong_lengths_are_format_errors(void)
{
    for (int kind = CTRLBUS_REQ_CONNECT_BASE; kind < CTRLBUS_REQ_HEALTH_UNKNOWN; kind++) {
        ctrlbus_request_t r = request_of((ctrlbus_req_kind_t)kind);
        r.as.connect_base.protocol_version = CTRLBUS_PROTOCOL_VERSION; /* only read for CONNECT */
        if (kind != CTRLBUS_REQ_CONNECT_BASE) {
            r = request_of((ctrlbus_req_kind_t)kind);
        }
        uint8_t wire[64];
        uint8_t payload[64];
        harness_context("%s", ctrlbus_request_name(r.kind));
        int32_t len = ctrlbus_request_encode(wire, sizeof wire, &r, CTRLBUS_FRAME_STANDARD);
        size_t payload_len = (size_t)len - CTRLBUS_STANDARD_OVERHEAD;
        memcpy(payload, wire + 3, payload_len);
        payload[payload_len] = 0;
        ctrlbus_request_t d;
        CHECK_EQ(ctrlbus_request_decode(&d, wire[2], payload, payload_len + 1),
                 CTRLBUS_ERR_FORMAT);
        CHECK_EQ(d.kind, r.kind);
        CHECK_EQ(ctrlbus_request_error_code(&d, CTRLBUS_ERR_FORMAT), CTRLBUS_WIRE_ERR_FORMAT);
        bool header_only =
            payload_len == 1 || (payload[0] == CTRLBUS_CODE_HEALTH_MGMT && payload_len == 2);
        if (!header_only) {
            CHECK_EQ(ctrlbus_request_decode(&d, wire[2], payload, payload_len - 1),
                     CTRLBUS_ERR_FORMAT);
            CHECK_EQ(d.kind, r.kind);
        }
    }
    harness_context(NULL);
    ctrlbus_request_t d;
    uint8_t bytes[4] = {0x30, 0x00, 0x00, 0x00};
    CHECK_EQ(ctrlbus_request_decode(&d, CTRLBUS_CMD_CTRL_BUS, bytes, 2), CTRLBUS_ERR_FORMAT);
    CHECK_EQ(d.kind, CTRLBUS_REQ_GET_BASE_STATUS);
    CHECK_EQ(ctrlbus_request_decode(&d, CTRLBUS_CMD_CTRL_BUS, bytes, 0), CTRLBUS_ERR_FORMAT);
    CHECK_EQ(d.kind, CTRLBUS_REQ_NONE);
    bytes[0] = CTRLBUS_CODE_HEALTH_MGMT;
    CHECK_EQ(ctrlbus_request_decode(&d, CTRLBUS_CMD_CTRL_BUS, bytes, 1), CTRLBUS_ERR_FORMAT);
    CHECK_EQ(ctrlbus_request_error_code(&d, CTRLBUS_ERR_FORMAT), CTRLBUS_WIRE_ERR_FORMAT);
    CHECK_EQ(ctrlbus_request_decode(&d, CTRLBUS_CMD_BASE_CMD, bytes, 0), CTRLBUS_ERR_FORMAT);
    CHECK_EQ(ctrlbus_request_decode(&d, CTRLBUS_CMD_BASE_CMD, bytes, 2), CTRLBUS_ERR_FORMAT);
    CHECK_EQ(d.kind, CTRLBUS_REQ_BASE_CMD);
    CHECK_EQ(ctrlbus_request_decode(&d, CTRLBUS_CMD_CTRL_BUS, NULL, 1), CTRLBUS_ERR_ARGUMENT);
    CHECK_EQ(ctrlbus_request_decode(NULL, CTRLBUS_CMD_CTRL_BUS, bytes, 1), CTRLBUS_ERR_ARGUMENT);
    /* SYNC and ECHO take any length, nothing included. */
    CHECK_EQ(ctrlbus_request_decode(&d, CTRLBUS_CMD_SYNC, NULL, 0), CTRLBUS_OK);
    CHECK_EQ(d.as.sync.filler_len, 0);
    CHECK_EQ(ctrlbus_request_decode(&d, CTRLBUS_CMD_ECHO, bytes, 4), CTRLBUS_OK);
    CHECK(d.as.echo.data == bytes);
}

static void check_unsupported_value(uint8_t cmd, const char *payload_hex, ctrlbus_req_kind_t kind)
{
    uint8_t payload[8];
    size_t len = harness_unhex(payload, sizeof payload, payload_hex);
    ctrlbus_request_t d;
    harness_context("%s", payload_hex);
    CHECK_EQ(ctrlbus_request_decode(&d, cmd, payload, len), CTRLBUS_ERR_UNSUPPORTED);
    CHECK_EQ(d.kind, kind);
    CHECK_EQ(ctrlbus_request_error_code(&d, CTRLBUS_ERR_UNSUPPORTED), CTRLBUS_WIRE_ERR_UNSUPPORTED);
    /* What decoding refuses, encoding refuses too. */
    uint8_t out[16];
    CHECK_EQ(ctrlbus_request_encode(out, sizeof out, &d, CTRLBUS_FRAME_AUTO), CTRLBUS_ERR_ARGUMENT);
    /* With a wrong length as well, the length wins. */
    payload[len] = 0;
    CHECK_EQ(ctrlbus_request_decode(&d, cmd, payload, len + 1), CTRLBUS_ERR_FORMAT);
    harness_context(NULL);
}

static void test_unknown_argument_values_are_unsupported(void)
{
    check_unsupported_value(CTRLBUS_CMD_CTRL_BUS, "10 02", CTRLBUS_REQ_CONNECT_BASE);
    check_unsupported_value(CTRLBUS_CMD_CTRL_BUS, "10 00", CTRLBUS_REQ_CONNECT_BASE);
    check_unsupported_value(CTRLBUS_CMD_CTRL_BUS, "34 01", CTRLBUS_REQ_GET_CHARGER_DATA);
    check_unsupported_value(CTRLBUS_CMD_BASE_CMD, "03", CTRLBUS_REQ_BASE_CMD);
    check_unsupported_value(CTRLBUS_CMD_BASE_CMD, "00", CTRLBUS_REQ_BASE_CMD);
    ctrlbus_request_t d;
    uint8_t dfu = CTRLBUS_BASE_CMD_ENTER_DFU;
    CHECK_EQ(ctrlbus_request_decode(&d, CTRLBUS_CMD_BASE_CMD, &dfu, 1), CTRLBUS_OK);
}

static void test_answer_values_outside_the_layout(void)
{
    static uint8_t payload[264];
    ctrlbus_answer_t d;
    /* sensor_num / bumper_num over the 8 slots. */
    payload[6] = 9;
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_GET_BASE_CONF, CTRLBUS_CMD_OK, payload, 264),
             CTRLBUS_ERR_FORMAT);
    payload[6] = 8;
    payload[135] = 9;
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_GET_BASE_CONF, CTRLBUS_CMD_OK, payload, 264),
             CTRLBUS_ERR_FORMAT);
    payload[135] = 8;
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_GET_BASE_CONF, CTRLBUS_CMD_OK, payload, 264),
             CTRLBUS_OK);
    CHECK_EQ(d.as.get_base_conf.sensor_num, 8);
    CHECK_EQ(d.as.get_base_conf.bumper_num, 8);
    uint8_t out[300];
    d.as.get_base_conf.bumper_num = 9;
    CHECK_EQ(ctrlbus_answer_encode(out, sizeof out, &d, CTRLBUS_FRAME_LONG), CTRLBUS_ERR_ARGUMENT);

    /* Text is ASCII before the first NUL; what follows the NUL does not matter. */
    uint8_t connect[39] = {'c', 'a', 'f', 0xE9};
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_CONNECT_BASE, CTRLBUS_CMD_OK, connect, 28),
             CTRLBUS_ERR_FORMAT);
    connect[3] = 0;
    connect[4] = 0xE9;
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_CONNECT_BASE, CTRLBUS_CMD_OK, connect, 28),
             CTRLBUS_OK);
    CHECK_STR(d.as.connect_base.model, "caf");
    connect[28] = 'v';
    connect[29] = 0x80; /* in the suffix, before its NUL */
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_CONNECT_BASE, CTRLBUS_CMD_OK, connect, 39),
             CTRLBUS_ERR_FORMAT);
    connect[29] = '2';
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_CONNECT_BASE, CTRLBUS_CMD_OK, connect, 39),
             CTRLBUS_OK);
    CHECK_STR(d.as.connect_base.firmware_version_suffix, "v2");
    d.as.connect_base.model[1] = (char)0xC3;
    CHECK_EQ(ctrlbus_answer_encode(out, sizeof out, &d, CTRLBUS_FRAME_LONG), CTRLBUS_ERR_ARGUMENT);

    /* The HEALTH_GET_ERROR message must keep a NUL in its 32 bytes. */
    uint8_t error[36];
    memset(error, 'x', sizeof error);
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_HEALTH_GET_ERROR, CTRLBUS_CMD_OK, error, 36),
             CTRLBUS_ERR_FORMAT);
    error[35] = 0;
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_HEALTH_GET_ERROR, CTRLBUS_CMD_OK, error, 36),
             CTRLBUS_OK);
    CHECK_EQ(strlen(d.as.health_get_error.message), 31);
}

static void test_unknown_requests_are_unsupported(void)
{
    ctrlbus_request_t d;
    uint8_t bytes[4] = {0x11, 0, 0, 0};
    CHECK_EQ(ctrlbus_request_decode(&d, CTRLBUS_CMD_CTRL_BUS, bytes, 1), CTRLBUS_ERR_UNSUPPORTED);
    CHECK_EQ(d.kind, CTRLBUS_REQ_NONE);
    CHECK_EQ(ctrlbus_request_error_code(&d, CTRLBUS_ERR_UNSUPPORTED), CTRLBUS_WIRE_ERR_UNSUPPORTED);
    /* Every request code that is not in the table is unsupported, whatever the length. */
    int known = 0;
    for (unsigned code = 0; code < 256; code++) {
        bytes[0] = (uint8_t)code;
        bytes[1] = CTRLBUS_HEALTH_SUB_GET_HEALTH;
        int32_t result = ctrlbus_request_decode(&d, CTRLBUS_CMD_CTRL_BUS, bytes, 2);
        if (d.kind != CTRLBUS_REQ_NONE) {
            known++;
        } else {
            CHECK_EQ(result, CTRLBUS_ERR_UNSUPPORTED);
        }
    }
    CHECK_EQ(known, 15); /* the control-bus request codes of the contract's table */
    /* HEALTH with an unknown sub-command: unsupported, and answered with 0x8002. */
    uint8_t health[3] = {CTRLBUS_CODE_HEALTH_MGMT, 0x04, 0x00};
    CHECK_EQ(ctrlbus_request_decode(&d, CTRLBUS_CMD_CTRL_BUS, health, 2), CTRLBUS_ERR_UNSUPPORTED);
    CHECK_EQ(d.kind, CTRLBUS_REQ_HEALTH_UNKNOWN);
    CHECK_EQ(ctrlbus_request_error_code(&d, CTRLBUS_ERR_UNSUPPORTED), CTRLBUS_WIRE_ERR_OPERATION);
    health[1] = 0x00;
    CHECK_EQ(ctrlbus_request_decode(&d, CTRLBUS_CMD_CTRL_BUS, health, 3), CTRLBUS_ERR_UNSUPPORTED);
    CHECK_EQ(d.kind, CTRLBUS_REQ_HEALTH_UNKNOWN);
    /* Unknown CMDs, answer CMDs included. */
    static const uint8_t cmds[] = {0x02, 0x03, 0x04, 0x0F, 0x10, 0x50, 0xF7, 0xFA, 0xFF};
    for (size_t i = 0; i < sizeof cmds; i++) {
        CHECK_EQ(ctrlbus_request_decode(&d, cmds[i], bytes, 1), CTRLBUS_ERR_UNSUPPORTED);
        CHECK_EQ(d.kind, CTRLBUS_REQ_NONE);
    }
}

/* Which OK payload lengths each answer layout accepts. */
static void test_answer_lengths(void)
{
    static uint8_t payload[300];
    payload[1] = 3; /* a charger answer's probe_count */
    for (int to = CTRLBUS_REQ_BASE_CMD; to < CTRLBUS_REQ_HEALTH_UNKNOWN; to++) {
        if (to == CTRLBUS_REQ_GET_AUXILIARY_ANCHOR) {
            continue;
        }
        for (size_t len = 0; len <= sizeof payload; len++) {
            ctrlbus_answer_t d;
            harness_context("OK to %s, %zu bytes", ctrlbus_request_name((ctrlbus_req_kind_t)to),
                            len);
            int32_t result =
                ctrlbus_answer_decode(&d, (ctrlbus_req_kind_t)to, CTRLBUS_CMD_OK, payload, len);
            CHECK_EQ(result, answer_length_allowed((ctrlbus_req_kind_t)to, len) ? CTRLBUS_OK
                                                                         : CTRLBUS_ERR_FORMAT);
        }
    }
    harness_context(NULL);
    ctrlbus_answer_t d;
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_GET_BASE_STATUS, CTRLBUS_CMD_ERROR, payload, 1),
             CTRLBUS_ERR_FORMAT);
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_GET_BASE_STATUS, CTRLBUS_CMD_ERROR, payload, 3),
             CTRLBUS_ERR_FORMAT);
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_GET_BASE_STATUS, CTRLBUS_CMD_INVALID, payload, 1),
             CTRLBUS_ERR_FORMAT);
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_GET_BASE_STATUS, CTRLBUS_CMD_INVALID, NULL, 0),
             CTRLBUS_OK);
    CHECK_EQ(d.kind, CTRLBUS_ANSWER_INVALID);
    /* No OK layout: unsupported. Not a request: argument error. Unknown answer CMD. */
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_GET_AUXILIARY_ANCHOR, CTRLBUS_CMD_OK, payload, 4),
             CTRLBUS_ERR_UNSUPPORTED);
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_SYNC, CTRLBUS_CMD_OK, payload, 0),
             CTRLBUS_ERR_UNSUPPORTED);
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_NONE, CTRLBUS_CMD_OK, payload, 0),
             CTRLBUS_ERR_ARGUMENT);
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_HEALTH_UNKNOWN, CTRLBUS_CMD_OK, payload, 0),
             CTRLBUS_ERR_ARGUMENT);
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_GET_BASE_STATUS, 0x04, payload, 0),
             CTRLBUS_ERR_UNSUPPORTED);
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_GET_BASE_STATUS, 0xF8, payload, 0),
             CTRLBUS_ERR_UNSUPPORTED);
}

static void test_short_and_special_answer_forms(void)
{
    ctrlbus_answer_t d;
    uint8_t one = 0x02;
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_GET_BASE_BUMPER_DATA, CTRLBUS_CMD_OK, &one, 1),
             CTRLBUS_OK);
    CHECK_EQ(d.as.get_base_bumper_data.bitmap, 0x02); /* zero-padded, not sign- or one-filled */
    CHECK_EQ(d.as.get_base_bumper_data.payload_size, 1);

    uint8_t poll[2] = {0xFF, 0x37};
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_POLL_BASE_CMD, CTRLBUS_CMD_OK, poll, 2),
             CTRLBUS_OK);
    CHECK(!d.as.poll_base_cmd.has_command);
    CHECK_EQ(d.as.poll_base_cmd.pad, 0x37);
    poll[0] = 0x90;
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_POLL_BASE_CMD, CTRLBUS_CMD_OK, poll, 2),
             CTRLBUS_OK);
    CHECK(d.as.poll_base_cmd.has_command);
    CHECK_EQ(d.as.poll_base_cmd.command, 0x90);
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_POLL_BASE_CMD, CTRLBUS_CMD_OK, NULL, 0),
             CTRLBUS_OK);
    CHECK(!d.as.poll_base_cmd.has_command);
    CHECK_EQ(d.as.poll_base_cmd.payload_size, 0);

    /* Text: kept up to the first NUL. */
    uint8_t connect[28] = {'a', 'b', 0, 'c', 'd'};
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_CONNECT_BASE, CTRLBUS_CMD_OK, connect, 28),
             CTRLBUS_OK);
    CHECK_STR(d.as.connect_base.model, "ab");
    CHECK(!d.as.connect_base.has_firmware_version_suffix);

    /* Charger: the length must match probe_count. */
    uint8_t charger[6] = {3, 3, 1, 2, 4, 9};
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_GET_CHARGER_DATA, CTRLBUS_CMD_OK, charger, 5),
             CTRLBUS_OK);
    CHECK_EQ(d.as.get_charger_data.probes[2], 4);
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_GET_CHARGER_DATA, CTRLBUS_CMD_OK, charger, 6),
             CTRLBUS_ERR_FORMAT);
    CHECK_EQ(ctrlbus_answer_decode(&d, CTRLBUS_REQ_GET_CHARGER_DATA, CTRLBUS_CMD_OK, charger, 1),
             CTRLBUS_ERR_FORMAT);
}

static void test_inconsistent_answers_are_refused(void)
{
    uint8_t out[64];
    ctrlbus_answer_t a = ok_to(CTRLBUS_REQ_GET_BASE_BUMPER_DATA);
    a.as.get_base_bumper_data.payload_size = 0;
    CHECK_EQ(ctrlbus_answer_encode(out, sizeof out, &a, CTRLBUS_FRAME_LONG), CTRLBUS_ERR_ARGUMENT);
    a.as.get_base_bumper_data.payload_size = 5;
    CHECK_EQ(ctrlbus_answer_encode(out, sizeof out, &a, CTRLBUS_FRAME_LONG), CTRLBUS_ERR_ARGUMENT);
    a.as.get_base_bumper_data.payload_size = 1;
    a.as.get_base_bumper_data.bitmap = 0x100; /* does not fit in one byte */
    CHECK_EQ(ctrlbus_answer_encode(out, sizeof out, &a, CTRLBUS_FRAME_LONG), CTRLBUS_ERR_ARGUMENT);

    a = ok_to(CTRLBUS_REQ_POLL_BASE_CMD);
    a.as.poll_base_cmd.has_command = true;
    CHECK_EQ(ctrlbus_answer_encode(out, sizeof out, &a, CTRLBUS_FRAME_LONG), CTRLBUS_ERR_ARGUMENT);
    a.as.poll_base_cmd.has_command = false;
    a.as.poll_base_cmd.pad = 1;
    CHECK_EQ(ctrlbus_answer_encode(out, sizeof out, &a, CTRLBUS_FRAME_LONG), CTRLBUS_ERR_ARGUMENT);
    a.as.poll_base_cmd.payload_size = 1;
    CHECK_EQ(ctrlbus_answer_encode(out, sizeof out, &a, CTRLBUS_FRAME_LONG), CTRLBUS_ERR_ARGUMENT);
    a.as.poll_base_cmd.payload_size = 2;
    a.as.poll_base_cmd.has_command = true;
    a.as.poll_base_cmd.command = 0xFF; /* would read back as "nothing pending" */
    CHECK_EQ(ctrlbus_answer_encode(out, sizeof out, &a, CTRLBUS_FRAME_LONG), CTRLBUS_ERR_ARGUMENT);

    a = ok_to(CTRLBUS_REQ_HEALTH_GET_ERROR);
    memset(a.as.health_get_error.message, 'm', CTRLBUS_HEALTH_MESSAGE_LEN); /* 32: no NUL room */
    CHECK_EQ(ctrlbus_answer_encode(out, sizeof out, &a, CTRLBUS_FRAME_LONG), CTRLBUS_ERR_ARGUMENT);

    a = ok_to(CTRLBUS_REQ_GET_CHARGER_DATA);
    a.as.get_charger_data.probe_count = 2; /* probes missing */
    CHECK_EQ(ctrlbus_answer_encode(out, sizeof out, &a, CTRLBUS_FRAME_LONG), CTRLBUS_ERR_ARGUMENT);

    /* The layouts' own writers refuse the same structs before a byte is written. */
    size_t written = 1;
    CHECK_EQ(layout_write(&a, out, sizeof out, CTRLBUS_FRAME_LONG, &written), CTRLBUS_ERR_ARGUMENT);
    CHECK_EQ(written, 0);
    a = ok_to(CTRLBUS_REQ_GET_BASE_BUMPER_DATA); /* payload_size 0 */
    CHECK_EQ(layout_write(&a, out, sizeof out, CTRLBUS_FRAME_LONG, &written), CTRLBUS_ERR_ARGUMENT);
    CHECK_EQ(written, 0);
    a = ok_to(CTRLBUS_REQ_CONNECT_BASE);
    strcpy(a.as.connect_base.model, "caf\xe9"); /* not ASCII */
    CHECK_EQ(layout_write(&a, out, sizeof out, CTRLBUS_FRAME_LONG, &written), CTRLBUS_ERR_ARGUMENT);
    CHECK_EQ(written, 0);
    a = ok_to(CTRLBUS_REQ_GET_BASE_CONF);
    a.as.get_base_conf.bumper_num = 9;
    CHECK_EQ(layout_write(&a, out, sizeof out, CTRLBUS_FRAME_LONG, &written), CTRLBUS_ERR_ARGUMENT);
    CHECK_EQ(written, 0);
    a = ok_to(CTRLBUS_REQ_GET_BASE_CONF_ADV);
    a.as.get_base_conf_adv.blob_len = 3; /* blob NULL */
    CHECK_EQ(layout_write(&a, out, sizeof out, CTRLBUS_FRAME_LONG, &written), CTRLBUS_ERR_ARGUMENT);
    CHECK_EQ(written, 0);
    CHECK_EQ(ctrlbus_get_base_status_answer_write(NULL, NULL, CTRLBUS_FRAME_LONG),
             CTRLBUS_ERR_ARGUMENT);
    /* A standard frame cannot carry GET_BASE_CONF's 264 bytes: refused before any byte. */
    a = ok_to(CTRLBUS_REQ_GET_BASE_CONF);
    CHECK_EQ(layout_write(&a, out, sizeof out, CTRLBUS_FRAME_STANDARD, &written),
             CTRLBUS_ERR_TOO_BIG);
    CHECK_EQ(written, 0);

    a = ok_to(CTRLBUS_REQ_GET_AUXILIARY_ANCHOR);
    CHECK_EQ(ctrlbus_answer_encode(out, sizeof out, &a, CTRLBUS_FRAME_LONG), CTRLBUS_ERR_ARGUMENT);
    a = ok_to(CTRLBUS_REQ_SYNC);
    CHECK_EQ(ctrlbus_answer_encode(out, sizeof out, &a, CTRLBUS_FRAME_LONG), CTRLBUS_ERR_ARGUMENT);

    ctrlbus_request_t r = request_of(CTRLBUS_REQ_NONE);
    CHECK_EQ(ctrlbus_request_encode(out, sizeof out, &r, CTRLBUS_FRAME_AUTO), CTRLBUS_ERR_ARGUMENT);
    r.kind = CTRLBUS_REQ_HEALTH_UNKNOWN;
    CHECK_EQ(ctrlbus_request_encode(out, sizeof out, &r, CTRLBUS_FRAME_AUTO), CTRLBUS_ERR_ARGUMENT);
    r.kind = CTRLBUS_REQ_ECHO;
    r.as.echo.data_len = 3; /* data NULL */
    CHECK_EQ(ctrlbus_request_encode(out, sizeof out, &r, CTRLBUS_FRAME_AUTO), CTRLBUS_ERR_ARGUMENT);
    /* Too small a buffer. */
    r = request_of(CTRLBUS_REQ_SET_BASE_MOTOR);
    CHECK_EQ(ctrlbus_request_encode(out, 20, &r, CTRLBUS_FRAME_AUTO), CTRLBUS_ERR_TOO_BIG);
    CHECK_EQ(ctrlbus_request_encode(out, 21, &r, CTRLBUS_FRAME_AUTO), 21);
}

/* Text fields: what follows a text's NUL in its array goes out as zeros, and a text needs a NUL
 * within its array (the wire field's characters at most) with ASCII before it. */
static void test_text_fields_are_checked_and_zero_padded(void)
{
    enum { HEADER = 3 }; /* a standard frame: flag, length, cmd */
    uint8_t out[64];
    ctrlbus_answer_t a = ok_to(CTRLBUS_REQ_CONNECT_BASE);
    memset(a.as.connect_base.model, 'X', sizeof a.as.connect_base.model);
    memcpy(a.as.connect_base.model, "ab", 3); /* 'X' after the NUL */
    memset(a.as.connect_base.firmware_version_suffix, 0x80, 12); /* unused: no suffix */
    static const uint8_t model_field[CTRLBUS_MODEL_LEN] = {'a', 'b'};
    CHECK_EQ(ctrlbus_answer_encode(out, sizeof out, &a, CTRLBUS_FRAME_STANDARD),
             HEADER + (int32_t)CTRLBUS_CONNECT_BASE_ANSWER_SIZE + 1);
    CHECK_MEM(out + HEADER, sizeof model_field, model_field, sizeof model_field);

    a.as.connect_base.has_firmware_version_suffix = true; /* now the suffix counts */
    CHECK_EQ(ctrlbus_connect_base_answer_size(&a.as.connect_base), CTRLBUS_ERR_ARGUMENT);
    memset(a.as.connect_base.firmware_version_suffix, 'v', 12); /* 12 characters: no NUL */
    CHECK_EQ(ctrlbus_connect_base_answer_size(&a.as.connect_base), CTRLBUS_ERR_ARGUMENT);
    memset(a.as.connect_base.firmware_version_suffix, 'Y', 12);
    a.as.connect_base.firmware_version_suffix[1] = '\0';
    CHECK_EQ(ctrlbus_connect_base_answer_size(&a.as.connect_base),
             (int32_t)CTRLBUS_CONNECT_BASE_ANSWER_SIZE_WITH_SUFFIX);
    static const uint8_t suffix_field[CTRLBUS_FIRMWARE_VERSION_SUFFIX_LEN] = {'Y'};
    CHECK_EQ(ctrlbus_answer_encode(out, sizeof out, &a, CTRLBUS_FRAME_STANDARD),
             HEADER + (int32_t)CTRLBUS_CONNECT_BASE_ANSWER_SIZE_WITH_SUFFIX + 1);
    CHECK_MEM(out + HEADER + CTRLBUS_CONNECT_BASE_ANSWER_SIZE, sizeof suffix_field, suffix_field,
              sizeof suffix_field);
    memset(a.as.connect_base.model, 'm', sizeof a.as.connect_base.model); /* 13: no NUL */
    CHECK_EQ(ctrlbus_connect_base_answer_size(&a.as.connect_base), CTRLBUS_ERR_ARGUMENT);
    a.as.connect_base.model[0] = '\0'; /* empty: fine */
    CHECK_EQ(ctrlbus_connect_base_answer_size(&a.as.connect_base),
             (int32_t)CTRLBUS_CONNECT_BASE_ANSWER_SIZE_WITH_SUFFIX);
    a.as.connect_base.model[0] = 0x7F; /* DEL is ASCII; 0x80 is not (either char signedness) */
    a.as.connect_base.model[1] = (char)0x80;
    a.as.connect_base.model[2] = '\0';
    CHECK_EQ(ctrlbus_connect_base_answer_size(&a.as.connect_base), CTRLBUS_ERR_ARGUMENT);
    a.as.connect_base.model[1] = 0x01;
    CHECK_EQ(ctrlbus_connect_base_answer_size(&a.as.connect_base),
             (int32_t)CTRLBUS_CONNECT_BASE_ANSWER_SIZE_WITH_SUFFIX);
    CHECK_EQ(ctrlbus_connect_base_answer_size(NULL), CTRLBUS_ERR_ARGUMENT);

    a = ok_to(CTRLBUS_REQ_HEALTH_GET_ERROR);
    memset(a.as.health_get_error.message, 'Z', sizeof a.as.health_get_error.message);
    a.as.health_get_error.message[0] = 'e';
    a.as.health_get_error.message[1] = '\0';
    static const uint8_t message_field[CTRLBUS_HEALTH_MESSAGE_LEN] = {'e'};
    CHECK_EQ(ctrlbus_answer_encode(out, sizeof out, &a, CTRLBUS_FRAME_STANDARD),
             HEADER + (int32_t)CTRLBUS_HEALTH_GET_ERROR_ANSWER_SIZE + 1);
    CHECK_MEM(out + HEADER + 4, sizeof message_field, message_field, sizeof message_field);
    CHECK_EQ(ctrlbus_health_get_error_answer_size(NULL), CTRLBUS_ERR_ARGUMENT);
}

/* A base answers through a sink with no frame buffer: the per-layout put writes into a frame it
 * began itself. Writing fewer or more bytes than announced is caught. */
typedef struct {
    uint8_t bytes[400];
    size_t len;
    int calls;
} capture_t;

static int32_t capture_write(void *context, const uint8_t *data, size_t len)
{
    capture_t *c = context;
    c->calls++;
    memcpy(c->bytes + c->len, data, len);
    c->len += len;
    return CTRLBUS_OK;
}

static void test_streamed_answer_matches_buffer_encoding(void)
{
    ctrlbus_answer_t a = ok_to(CTRLBUS_REQ_GET_BASE_CONF);
    a.as.get_base_conf.sensor_num = 3;
    fill_position(&a.as.get_base_conf.sensors[2], 9);
    capture_t capture = {0};
    ctrlbus_sink_t sink;
    ctrlbus_sink_init(&sink, capture_write, &capture);
    CHECK_EQ(ctrlbus_sink_begin(&sink, CTRLBUS_CMD_OK, CTRLBUS_GET_BASE_CONF_ANSWER_SIZE,
                                CTRLBUS_FRAME_LONG),
             CTRLBUS_OK);
    ctrlbus_get_base_conf_answer_put(&sink, &a.as.get_base_conf);
    CHECK_EQ(ctrlbus_sink_end(&sink), 269);
    static uint8_t out[300];
    CHECK_EQ(ctrlbus_answer_encode(out, sizeof out, &a, CTRLBUS_FRAME_LONG), 269);
    CHECK_MEM(capture.bytes, capture.len, out, 269);
    CHECK(capture.calls > 5); /* streamed in pieces (header, fields, runs of words), not built */

    /* Announcing the 13-byte deadreckon size but putting the 17-byte form fails. */
    ctrlbus_set_v_and_get_deadreckon_answer_t dr;
    memset(&dr, 0, sizeof dr);
    dr.has_timestamp_ms = true;
    capture.len = 0;
    ctrlbus_sink_begin(&sink, CTRLBUS_CMD_OK, CTRLBUS_SET_V_AND_GET_DEADRECKON_ANSWER_SIZE,
                       CTRLBUS_FRAME_LONG);
    ctrlbus_set_v_and_get_deadreckon_answer_put(&sink, &dr);
    CHECK_EQ(ctrlbus_sink_end(&sink), CTRLBUS_ERR_LENGTH);
}

static void test_names(void)
{
    for (int i = CTRLBUS_REQ_SYNC; i < CTRLBUS_REQ_HEALTH_UNKNOWN; i++) {
        const char *name = ctrlbus_request_name((ctrlbus_req_kind_t)i);
        CHECK(name != NULL);
        for (int k = CTRLBUS_REQ_SYNC; k < i && name != NULL; k++) {
            CHECK(strcmp(name, ctrlbus_request_name((ctrlbus_req_kind_t)k)) != 0);
        }
        CHECK(ctrlbus_request_cmd((ctrlbus_req_kind_t)i) >= 0);
    }
    CHECK(ctrlbus_request_name(CTRLBUS_REQ_NONE) == NULL);
    CHECK(ctrlbus_request_name(CTRLBUS_REQ_HEALTH_UNKNOWN) == NULL);
    CHECK(ctrlbus_request_name(CTRLBUS_REQ_COUNT) == NULL);
    CHECK_EQ(ctrlbus_request_cmd(CTRLBUS_REQ_NONE), -1);
    CHECK_STR(ctrlbus_request_name(CTRLBUS_REQ_SET_V_AND_GET_DEADRECKON),
              "SET_V_AND_GET_DEADRECKON");
    CHECK_STR(ctrlbus_answer_name(CTRLBUS_ANSWER_INVALID), "INVALID");
    CHECK_STR(ctrlbus_error_name(CTRLBUS_ERR_FORMAT), "format");
    CHECK_STR(ctrlbus_error_name(-99), "unknown");
}

int main(void)
{
    RUN(test_every_request_round_trips);
    RUN(test_every_answer_round_trips);
    RUN(test_reference_example_frames);
    RUN(test_request_wrong_lengths_are_format_errors);
    RUN(test_unknown_requests_are_unsupported);
    RUN(test_unknown_argument_values_are_unsupported);
    RUN(test_answer_values_outside_the_layout);
    RUN(test_answer_lengths);
    RUN(test_short_and_special_answer_forms);
    RUN(test_inconsistent_answers_are_refused);
    RUN(test_text_fields_are_checked_and_zero_padded);
    RUN(test_streamed_answer_matches_buffer_encoding);
    RUN(test_names);
    return harness_finish();
}
