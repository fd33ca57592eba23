/* SPDX-License-Identifier: MIT */
/* Typed requests and answers, serialised field by field (see ctrlbus/messages.h). This file is a
 * base's half: decoding requests, encoding answers. The master's half (encoding requests,
 * decoding answers) is messages_master.c. */
#include "ctrlbus/messages.h"

#include "codec.h"

static void put_position(ctrlbus_sink_t *sink, const ctrlbus_position_t *position)
{
    ctrlbus_sink_put_s32(sink, position->x_mm_q8);
    ctrlbus_sink_put_s32(sink, position->y_mm_q8);
    ctrlbus_sink_put_s32(sink, position->z_mm_q8);
    ctrlbus_sink_put_u32(sink, position->angle_deg_q8);
}

/* Whether text (up to its NUL, at most max_chars characters) can be written as a text field:
 * ASCII, and not longer than max_chars. */
static bool text_ok(const char *text, size_t array_size, size_t max_chars)
{
    size_t len = 0;
    while (len < array_size && text[len] != '\0') {
        if ((unsigned char)text[len] > 0x7Fu) {
            return false;
        }
        len++;
    }
    return len <= max_chars;
}

/* ---- requests ------------------------------------------------------------------------------- */

static const char *const REQUEST_NAMES[CTRLBUS_REQ_COUNT] = {
    [CTRLBUS_REQ_SYNC] = "SYNC",
    [CTRLBUS_REQ_ECHO] = "ECHO",
    [CTRLBUS_REQ_BASE_CMD] = "BASE_CMD",
    [CTRLBUS_REQ_CONNECT_BASE] = "CONNECT_BASE",
    [CTRLBUS_REQ_GET_BASE_CONF] = "GET_BASE_CONF",
    [CTRLBUS_REQ_GET_BASE_CONF_ADV] = "GET_BASE_CONF_ADV",
    [CTRLBUS_REQ_GET_BASE_STATUS] = "GET_BASE_STATUS",
    [CTRLBUS_REQ_GET_BASE_MOTOR_DATA] = "GET_BASE_MOTOR_DATA",
    [CTRLBUS_REQ_GET_BASE_SENSOR_DATA] = "GET_BASE_SENSOR_DATA",
    [CTRLBUS_REQ_GET_BASE_BUMPER_DATA] = "GET_BASE_BUMPER_DATA",
    [CTRLBUS_REQ_GET_CHARGER_DATA] = "GET_CHARGER_DATA",
    [CTRLBUS_REQ_GET_AUXILIARY_ANCHOR] = "GET_AUXILIARY_ANCHOR",
    [CTRLBUS_REQ_SET_BASE_MOTOR] = "SET_BASE_MOTOR",
    [CTRLBUS_REQ_SET_V_AND_GET_DEADRECKON] = "SET_V_AND_GET_DEADRECKON",
    [CTRLBUS_REQ_POLL_BASE_CMD] = "POLL_BASE_CMD",
    [CTRLBUS_REQ_POLL_BASE_ANS_CMD] = "POLL_BASE_ANS_CMD",
    [CTRLBUS_REQ_SEND_EVENT] = "SEND_EVENT",
    [CTRLBUS_REQ_HEALTH_GET_HEALTH] = "HEALTH_GET_HEALTH",
    [CTRLBUS_REQ_HEALTH_GET_ERROR] = "HEALTH_GET_ERROR",
    [CTRLBUS_REQ_HEALTH_CLR_ERROR] = "HEALTH_CLR_ERROR",
};

const char *ctrlbus_request_name(ctrlbus_req_kind_t kind)
{
    return (unsigned)kind < CTRLBUS_REQ_COUNT ? REQUEST_NAMES[kind] : NULL;
}

uint16_t ctrlbus_request_error_code(const ctrlbus_request_t *request, int32_t error)
{
    if (error == CTRLBUS_ERR_FORMAT) {
        return CTRLBUS_WIRE_ERR_FORMAT;
    }
    if (error == CTRLBUS_ERR_UNSUPPORTED && request != NULL &&
        request->kind == CTRLBUS_REQ_HEALTH_UNKNOWN) {
        return CTRLBUS_WIRE_ERR_OPERATION;
    }
    return CTRLBUS_WIRE_ERR_UNSUPPORTED;
}

/* Sets the request's kind and checks its payload length: CTRLBUS_OK or CTRLBUS_ERR_FORMAT. */
static int32_t expect(ctrlbus_request_t *out, ctrlbus_req_kind_t kind, size_t len, size_t size)
{
    out->kind = kind;
    return len == size ? CTRLBUS_OK : CTRLBUS_ERR_FORMAT;
}

static int32_t supported_if(bool known)
{
    return known ? CTRLBUS_OK : CTRLBUS_ERR_UNSUPPORTED;
}

/* HEALTH_MGMT: the sub-command (payload[1]) picks the request; len >= 2. */
static int32_t decode_health(ctrlbus_request_t *out, const uint8_t *payload, size_t len)
{
    const uint8_t *args = payload + 2;
    int32_t result;
    switch (payload[1]) {
    case CTRLBUS_HEALTH_SUB_GET_HEALTH:
        return expect(out, CTRLBUS_REQ_HEALTH_GET_HEALTH, len,
                      CTRLBUS_HEALTH_GET_HEALTH_REQUEST_SIZE);
    case CTRLBUS_HEALTH_SUB_GET_ERROR:
        result = expect(out, CTRLBUS_REQ_HEALTH_GET_ERROR, len,
                        CTRLBUS_HEALTH_GET_ERROR_REQUEST_SIZE);
        if (result == CTRLBUS_OK) {
            out->as.health_get_error.index = codec_take_u8(&args);
        }
        return result;
    case CTRLBUS_HEALTH_SUB_CLR_ERROR:
        result = expect(out, CTRLBUS_REQ_HEALTH_CLR_ERROR, len,
                        CTRLBUS_HEALTH_CLR_ERROR_REQUEST_SIZE);
        if (result == CTRLBUS_OK) {
            out->as.health_clr_error.error_code = codec_take_u32(&args);
        }
        return result;
    default: out->kind = CTRLBUS_REQ_HEALTH_UNKNOWN; return CTRLBUS_ERR_UNSUPPORTED;
    }
}

/* A CMD 0xF8 payload: one switch on the request code finds the request, checks its length (before
 * any value: a wrong length with a bad value is a FORMAT error), reads its arguments and checks
 * their values. */
static int32_t decode_ctrl_bus(ctrlbus_request_t *out, const uint8_t *payload, size_t len)
{
    if (len == 0) {
        return CTRLBUS_ERR_FORMAT; /* no request code at all */
    }
    const uint8_t *args = payload + 1;
    int32_t result;
    switch (payload[0]) {
    case CTRLBUS_CODE_CONNECT_BASE:
        result = expect(out, CTRLBUS_REQ_CONNECT_BASE, len, CTRLBUS_CONNECT_BASE_REQUEST_SIZE);
        if (result == CTRLBUS_OK) {
            out->as.connect_base.protocol_version = args[0];
            result = supported_if(codec_connect_version_known(args[0]));
        }
        return result;
    case CTRLBUS_CODE_GET_BASE_CONF:
        return expect(out, CTRLBUS_REQ_GET_BASE_CONF, len, CTRLBUS_PLAIN_REQUEST_SIZE);
    case CTRLBUS_CODE_GET_BASE_CONF_ADV:
        return expect(out, CTRLBUS_REQ_GET_BASE_CONF_ADV, len, CTRLBUS_PLAIN_REQUEST_SIZE);
    case CTRLBUS_CODE_GET_BASE_STATUS:
        return expect(out, CTRLBUS_REQ_GET_BASE_STATUS, len, CTRLBUS_PLAIN_REQUEST_SIZE);
    case CTRLBUS_CODE_GET_BASE_MOTOR_DATA:
        return expect(out, CTRLBUS_REQ_GET_BASE_MOTOR_DATA, len, CTRLBUS_PLAIN_REQUEST_SIZE);
    case CTRLBUS_CODE_GET_BASE_SENSOR_DATA:
        return expect(out, CTRLBUS_REQ_GET_BASE_SENSOR_DATA, len, CTRLBUS_PLAIN_REQUEST_SIZE);
    case CTRLBUS_CODE_GET_BASE_BUMPER_DATA:
        return expect(out, CTRLBUS_REQ_GET_BASE_BUMPER_DATA, len, CTRLBUS_PLAIN_REQUEST_SIZE);
    case CTRLBUS_CODE_GET_CHARGER_DATA:
        result = expect(out, CTRLBUS_REQ_GET_CHARGER_DATA, len,
                        CTRLBUS_GET_CHARGER_DATA_REQUEST_SIZE);
        if (result == CTRLBUS_OK) {
            out->as.get_charger_data.data_type = args[0];
            result = supported_if(codec_charger_type_known(args[0]));
        }
        return result;
    case CTRLBUS_CODE_GET_AUXILIARY_ANCHOR:
        return expect(out, CTRLBUS_REQ_GET_AUXILIARY_ANCHOR, len, CTRLBUS_PLAIN_REQUEST_SIZE);
    case CTRLBUS_CODE_SET_BASE_MOTOR:
        result = expect(out, CTRLBUS_REQ_SET_BASE_MOTOR, len, CTRLBUS_SET_BASE_MOTOR_REQUEST_SIZE);
        for (size_t i = 0; result == CTRLBUS_OK && i < CTRLBUS_MOTOR_SPEEDS; i++) {
            out->as.set_base_motor.speeds_mm_s[i] = codec_take_s32(&args);
        }
        return result;
    case CTRLBUS_CODE_SET_V_AND_GET_DEADRECKON:
        result = expect(out, CTRLBUS_REQ_SET_V_AND_GET_DEADRECKON, len,
                        CTRLBUS_SET_V_AND_GET_DEADRECKON_REQUEST_SIZE);
        if (result == CTRLBUS_OK) {
            out->as.set_v_and_get_deadreckon.vx_mps_q16 = codec_take_s32(&args);
            out->as.set_v_and_get_deadreckon.vy_mps_q16 = codec_take_s32(&args);
            out->as.set_v_and_get_deadreckon.omega_radps_q16 = codec_take_s32(&args);
        }
        return result;
    case CTRLBUS_CODE_POLL_BASE_CMD:
        return expect(out, CTRLBUS_REQ_POLL_BASE_CMD, len, CTRLBUS_PLAIN_REQUEST_SIZE);
    case CTRLBUS_CODE_POLL_BASE_ANS_CMD:
        return expect(out, CTRLBUS_REQ_POLL_BASE_ANS_CMD, len, CTRLBUS_PLAIN_REQUEST_SIZE);
    case CTRLBUS_CODE_SEND_EVENT:
        result = expect(out, CTRLBUS_REQ_SEND_EVENT, len, CTRLBUS_SEND_EVENT_REQUEST_SIZE);
        if (result == CTRLBUS_OK) {
            out->as.send_event.event = args[0];
        }
        return result;
    case CTRLBUS_CODE_HEALTH_MGMT:
        return len < 2 ? CTRLBUS_ERR_FORMAT : decode_health(out, payload, len);
    default: return CTRLBUS_ERR_UNSUPPORTED; /* out->kind stays CTRLBUS_REQ_NONE */
    }
}

int32_t ctrlbus_request_decode(ctrlbus_request_t *out, uint8_t cmd, const uint8_t *payload,
                               size_t len)
{
    if (out == NULL || (payload == NULL && len > 0)) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    out->kind = CTRLBUS_REQ_NONE;
    switch (cmd) {
    case CTRLBUS_CMD_SYNC:
        out->kind = CTRLBUS_REQ_SYNC;
        out->as.sync.filler = payload;
        out->as.sync.filler_len = len;
        return CTRLBUS_OK;
    case CTRLBUS_CMD_ECHO:
        out->kind = CTRLBUS_REQ_ECHO;
        out->as.echo.data = payload;
        out->as.echo.data_len = len;
        return CTRLBUS_OK;
    case CTRLBUS_CMD_BASE_CMD: {
        int32_t result = expect(out, CTRLBUS_REQ_BASE_CMD, len, CTRLBUS_BASE_CMD_REQUEST_SIZE);
        if (result == CTRLBUS_OK) {
            out->as.base_cmd.subcommand = payload[0];
            result = supported_if(codec_base_cmd_known(payload[0]));
        }
        return result;
    }
    case CTRLBUS_CMD_CTRL_BUS: return decode_ctrl_bus(out, payload, len);
    default: return CTRLBUS_ERR_UNSUPPORTED;
    }
}

/* ---- answers: one encoder per layout -------------------------------------------------------- */

int32_t ctrlbus_codec_write_ok(ctrlbus_sink_t *sink, int32_t size, ctrlbus_codec_put_fn put,
                               const void *answer, ctrlbus_frame_type_t type)
{
    if (size < 0) {
        return size;
    }
    int32_t result = ctrlbus_sink_begin(sink, CTRLBUS_CMD_OK, (size_t)size, type);
    if (result < 0) {
        return result;
    }
    if (put != NULL) {
        put(sink, answer);
    }
    return ctrlbus_sink_end(sink);
}

/* The per-layout _put: the check, then the fields (a bad struct fails the sink's frame). */
static void put_checked(ctrlbus_sink_t *sink, int32_t size, ctrlbus_codec_put_fn put,
                        const void *answer)
{
    if (size < 0) {
        ctrlbus_sink_fail(sink, size);
        return;
    }
    put(sink, answer);
}

/* The size of a layout whose size and values cannot vary. */
static int32_t fixed_size(const void *answer, uint32_t size)
{
    return answer != NULL ? (int32_t)size : CTRLBUS_ERR_ARGUMENT;
}

static int32_t bytes_size(const uint8_t *bytes, size_t len)
{
    if (bytes == NULL && len > 0) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    return len > CTRLBUS_LONG_PAYLOAD_MAX ? CTRLBUS_ERR_TOO_BIG : (int32_t)len;
}

/* CONNECT_BASE */

int32_t ctrlbus_connect_base_answer_size(const ctrlbus_connect_base_answer_t *a)
{
    if (a == NULL || !text_ok(a->model, sizeof a->model, CTRLBUS_MODEL_LEN) ||
        (a->has_firmware_version_suffix &&
         !text_ok(a->firmware_version_suffix, sizeof a->firmware_version_suffix,
                  CTRLBUS_FIRMWARE_VERSION_SUFFIX_LEN))) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    return a->has_firmware_version_suffix ? CTRLBUS_CONNECT_BASE_ANSWER_SIZE_WITH_SUFFIX
                                          : CTRLBUS_CONNECT_BASE_ANSWER_SIZE;
}

void ctrlbus_codec_connect_base_fields(ctrlbus_sink_t *sink, const void *answer)
{
    const ctrlbus_connect_base_answer_t *a = answer;
    ctrlbus_sink_put_text(sink, a->model, CTRLBUS_MODEL_LEN);
    ctrlbus_sink_put_u16(sink, a->firmware_version);
    ctrlbus_sink_put_u16(sink, a->hardware_version);
    for (size_t i = 0; i < CTRLBUS_SERIAL_WORDS; i++) {
        ctrlbus_sink_put_u32(sink, a->serial[i]);
    }
    if (a->has_firmware_version_suffix) {
        ctrlbus_sink_put_text(sink, a->firmware_version_suffix,
                              CTRLBUS_FIRMWARE_VERSION_SUFFIX_LEN);
    }
}

void ctrlbus_connect_base_answer_put(ctrlbus_sink_t *sink, const ctrlbus_connect_base_answer_t *a)
{
    put_checked(sink, ctrlbus_connect_base_answer_size(a), ctrlbus_codec_connect_base_fields, a);
}

int32_t ctrlbus_connect_base_answer_write(ctrlbus_sink_t *sink,
                                          const ctrlbus_connect_base_answer_t *a,
                                          ctrlbus_frame_type_t type)
{
    return ctrlbus_codec_write_ok(sink, ctrlbus_connect_base_answer_size(a),
                                  ctrlbus_codec_connect_base_fields, a, type);
}

/* GET_BASE_CONF */

int32_t ctrlbus_get_base_conf_answer_size(const ctrlbus_get_base_conf_answer_t *a)
{
    if (a == NULL || a->sensor_num > CTRLBUS_CONF_SLOTS || a->bumper_num > CTRLBUS_CONF_SLOTS) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    return CTRLBUS_GET_BASE_CONF_ANSWER_SIZE;
}

static void put_positions(ctrlbus_sink_t *sink, const ctrlbus_position_t *positions)
{
    for (size_t i = 0; i < CTRLBUS_CONF_SLOTS; i++) {
        put_position(sink, &positions[i]);
    }
}

void ctrlbus_codec_get_base_conf_fields(ctrlbus_sink_t *sink, const void *answer)
{
    const ctrlbus_get_base_conf_answer_t *a = answer;
    ctrlbus_sink_put_u8(sink, a->base_type);
    ctrlbus_sink_put_u32(sink, a->base_radius_mm_q8);
    ctrlbus_sink_put_u8(sink, a->motor_type);
    ctrlbus_sink_put_u8(sink, a->sensor_num);
    put_positions(sink, a->sensors);
    ctrlbus_sink_put_u8(sink, a->bumper_num);
    put_positions(sink, a->bumpers);
}

void ctrlbus_get_base_conf_answer_put(ctrlbus_sink_t *sink, const ctrlbus_get_base_conf_answer_t *a)
{
    put_checked(sink, ctrlbus_get_base_conf_answer_size(a), ctrlbus_codec_get_base_conf_fields, a);
}

int32_t ctrlbus_get_base_conf_answer_write(ctrlbus_sink_t *sink,
                                           const ctrlbus_get_base_conf_answer_t *a,
                                           ctrlbus_frame_type_t type)
{
    return ctrlbus_codec_write_ok(sink, ctrlbus_get_base_conf_answer_size(a),
                                  ctrlbus_codec_get_base_conf_fields, a, type);
}

/* GET_BASE_CONF_ADV */

static int32_t get_base_conf_adv_size(const ctrlbus_get_base_conf_adv_answer_t *a)
{
    return a != NULL ? bytes_size(a->blob, a->blob_len) : CTRLBUS_ERR_ARGUMENT;
}

void ctrlbus_codec_get_base_conf_adv_fields(ctrlbus_sink_t *sink, const void *answer)
{
    const ctrlbus_get_base_conf_adv_answer_t *a = answer;
    ctrlbus_sink_put(sink, a->blob, a->blob_len);
}

void ctrlbus_get_base_conf_adv_answer_put(ctrlbus_sink_t *sink,
                                          const ctrlbus_get_base_conf_adv_answer_t *a)
{
    put_checked(sink, get_base_conf_adv_size(a), ctrlbus_codec_get_base_conf_adv_fields, a);
}

int32_t ctrlbus_get_base_conf_adv_answer_write(ctrlbus_sink_t *sink,
                                               const ctrlbus_get_base_conf_adv_answer_t *a,
                                               ctrlbus_frame_type_t type)
{
    return ctrlbus_codec_write_ok(sink, get_base_conf_adv_size(a),
                                  ctrlbus_codec_get_base_conf_adv_fields, a, type);
}

/* GET_BASE_STATUS */

void ctrlbus_codec_get_base_status_fields(ctrlbus_sink_t *sink, const void *answer)
{
    const ctrlbus_get_base_status_answer_t *a = answer;
    ctrlbus_sink_put_u8(sink, a->battery_percent);
    ctrlbus_sink_put_u8(sink, a->power_status);
}

void ctrlbus_get_base_status_answer_put(ctrlbus_sink_t *sink,
                                        const ctrlbus_get_base_status_answer_t *a)
{
    put_checked(sink, fixed_size(a, CTRLBUS_GET_BASE_STATUS_ANSWER_SIZE),
                ctrlbus_codec_get_base_status_fields, a);
}

int32_t ctrlbus_get_base_status_answer_write(ctrlbus_sink_t *sink,
                                             const ctrlbus_get_base_status_answer_t *a,
                                             ctrlbus_frame_type_t type)
{
    return ctrlbus_codec_write_ok(sink, fixed_size(a, CTRLBUS_GET_BASE_STATUS_ANSWER_SIZE),
                                  ctrlbus_codec_get_base_status_fields, a, type);
}

/* GET_BASE_MOTOR_DATA */

void ctrlbus_codec_get_base_motor_data_fields(ctrlbus_sink_t *sink, const void *answer)
{
    const ctrlbus_get_base_motor_data_answer_t *a = answer;
    ctrlbus_sink_put_s32(sink, a->left_distance_mm);
    ctrlbus_sink_put_s32(sink, a->right_distance_mm);
    ctrlbus_sink_put_u8(sink, a->status);
}

void ctrlbus_get_base_motor_data_answer_put(ctrlbus_sink_t *sink,
                                            const ctrlbus_get_base_motor_data_answer_t *a)
{
    put_checked(sink, fixed_size(a, CTRLBUS_GET_BASE_MOTOR_DATA_ANSWER_SIZE),
                ctrlbus_codec_get_base_motor_data_fields, a);
}

int32_t ctrlbus_get_base_motor_data_answer_write(ctrlbus_sink_t *sink,
                                                 const ctrlbus_get_base_motor_data_answer_t *a,
                                                 ctrlbus_frame_type_t type)
{
    return ctrlbus_codec_write_ok(sink, fixed_size(a, CTRLBUS_GET_BASE_MOTOR_DATA_ANSWER_SIZE),
                                  ctrlbus_codec_get_base_motor_data_fields, a, type);
}

/* GET_BASE_SENSOR_DATA */

void ctrlbus_codec_get_base_sensor_data_fields(ctrlbus_sink_t *sink, const void *answer)
{
    const ctrlbus_get_base_sensor_data_answer_t *a = answer;
    for (size_t i = 0; i < CTRLBUS_SENSOR_CHANNELS; i++) {
        ctrlbus_sink_put_u32(sink, a->distances_mm_q16[i]);
    }
}

void ctrlbus_get_base_sensor_data_answer_put(ctrlbus_sink_t *sink,
                                             const ctrlbus_get_base_sensor_data_answer_t *a)
{
    put_checked(sink, fixed_size(a, CTRLBUS_GET_BASE_SENSOR_DATA_ANSWER_SIZE),
                ctrlbus_codec_get_base_sensor_data_fields, a);
}

int32_t ctrlbus_get_base_sensor_data_answer_write(ctrlbus_sink_t *sink,
                                                  const ctrlbus_get_base_sensor_data_answer_t *a,
                                                  ctrlbus_frame_type_t type)
{
    return ctrlbus_codec_write_ok(sink, fixed_size(a, CTRLBUS_GET_BASE_SENSOR_DATA_ANSWER_SIZE),
                                  ctrlbus_codec_get_base_sensor_data_fields, a, type);
}

/* GET_BASE_BUMPER_DATA */

int32_t ctrlbus_get_base_bumper_data_answer_size(const ctrlbus_get_base_bumper_data_answer_t *a)
{
    if (a == NULL || a->payload_size < 1 || a->payload_size > 4) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    /* Bits above payload_size bytes cannot be sent: refuse rather than drop them. */
    if (a->payload_size < 4 && (a->bitmap >> (8u * a->payload_size)) != 0) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    return a->payload_size;
}

void ctrlbus_codec_get_base_bumper_data_fields(ctrlbus_sink_t *sink, const void *answer)
{
    const ctrlbus_get_base_bumper_data_answer_t *a = answer;
    for (uint8_t i = 0; i < a->payload_size; i++) {
        ctrlbus_sink_put_u8(sink, (uint8_t)((a->bitmap >> (8u * i)) & 0xFFu));
    }
}

void ctrlbus_get_base_bumper_data_answer_put(ctrlbus_sink_t *sink,
                                             const ctrlbus_get_base_bumper_data_answer_t *a)
{
    put_checked(sink, ctrlbus_get_base_bumper_data_answer_size(a),
                ctrlbus_codec_get_base_bumper_data_fields, a);
}

int32_t ctrlbus_get_base_bumper_data_answer_write(ctrlbus_sink_t *sink,
                                                  const ctrlbus_get_base_bumper_data_answer_t *a,
                                                  ctrlbus_frame_type_t type)
{
    return ctrlbus_codec_write_ok(sink, ctrlbus_get_base_bumper_data_answer_size(a),
                                  ctrlbus_codec_get_base_bumper_data_fields, a, type);
}

/* GET_CHARGER_DATA */

int32_t ctrlbus_get_charger_data_answer_size(const ctrlbus_get_charger_data_answer_t *a)
{
    if (a == NULL || (a->probes == NULL && a->probe_count > 0)) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    return (int32_t)CTRLBUS_GET_CHARGER_DATA_ANSWER_MIN + a->probe_count;
}

void ctrlbus_codec_get_charger_data_fields(ctrlbus_sink_t *sink, const void *answer)
{
    const ctrlbus_get_charger_data_answer_t *a = answer;
    ctrlbus_sink_put_u8(sink, a->beacon_count);
    ctrlbus_sink_put_u8(sink, a->probe_count);
    ctrlbus_sink_put(sink, a->probes, a->probe_count);
}

void ctrlbus_get_charger_data_answer_put(ctrlbus_sink_t *sink,
                                         const ctrlbus_get_charger_data_answer_t *a)
{
    put_checked(sink, ctrlbus_get_charger_data_answer_size(a),
                ctrlbus_codec_get_charger_data_fields, a);
}

int32_t ctrlbus_get_charger_data_answer_write(ctrlbus_sink_t *sink,
                                              const ctrlbus_get_charger_data_answer_t *a,
                                              ctrlbus_frame_type_t type)
{
    return ctrlbus_codec_write_ok(sink, ctrlbus_get_charger_data_answer_size(a),
                                  ctrlbus_codec_get_charger_data_fields, a, type);
}

/* SET_V_AND_GET_DEADRECKON */

int32_t ctrlbus_set_v_and_get_deadreckon_answer_size(
    const ctrlbus_set_v_and_get_deadreckon_answer_t *a)
{
    if (a == NULL) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    return a->has_timestamp_ms ? CTRLBUS_SET_V_AND_GET_DEADRECKON_ANSWER_SIZE_WITH_TIMESTAMP
                               : CTRLBUS_SET_V_AND_GET_DEADRECKON_ANSWER_SIZE;
}

void ctrlbus_codec_set_v_and_get_deadreckon_fields(ctrlbus_sink_t *sink, const void *answer)
{
    const ctrlbus_set_v_and_get_deadreckon_answer_t *a = answer;
    ctrlbus_sink_put_s32(sink, a->dx_mm_q16);
    ctrlbus_sink_put_s32(sink, a->dy_mm_q16);
    ctrlbus_sink_put_s32(sink, a->dtheta_deg_q16);
    ctrlbus_sink_put_u8(sink, a->status);
    if (a->has_timestamp_ms) {
        ctrlbus_sink_put_u32(sink, a->timestamp_ms);
    }
}

void ctrlbus_set_v_and_get_deadreckon_answer_put(
    ctrlbus_sink_t *sink, const ctrlbus_set_v_and_get_deadreckon_answer_t *a)
{
    put_checked(sink, ctrlbus_set_v_and_get_deadreckon_answer_size(a),
                ctrlbus_codec_set_v_and_get_deadreckon_fields, a);
}

int32_t ctrlbus_set_v_and_get_deadreckon_answer_write(
    ctrlbus_sink_t *sink, const ctrlbus_set_v_and_get_deadreckon_answer_t *a,
    ctrlbus_frame_type_t type)
{
    return ctrlbus_codec_write_ok(sink, ctrlbus_set_v_and_get_deadreckon_answer_size(a),
                                  ctrlbus_codec_set_v_and_get_deadreckon_fields, a, type);
}

/* POLL_BASE_CMD */

int32_t ctrlbus_poll_base_cmd_answer_size(const ctrlbus_poll_base_cmd_answer_t *a)
{
    if (a == NULL) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    if (a->payload_size == 0) {
        return a->has_command || a->pad != 0 ? CTRLBUS_ERR_ARGUMENT : 0;
    }
    if (a->payload_size != CTRLBUS_POLL_BASE_CMD_ANSWER_SIZE ||
        (a->has_command && a->command == CTRLBUS_POLL_NOTHING_PENDING)) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    return CTRLBUS_POLL_BASE_CMD_ANSWER_SIZE;
}

void ctrlbus_codec_poll_base_cmd_fields(ctrlbus_sink_t *sink, const void *answer)
{
    const ctrlbus_poll_base_cmd_answer_t *a = answer;
    if (a->payload_size > 0) {
        ctrlbus_sink_put_u8(sink, a->has_command ? a->command : CTRLBUS_POLL_NOTHING_PENDING);
        ctrlbus_sink_put_u8(sink, a->pad);
    }
}

void ctrlbus_poll_base_cmd_answer_put(ctrlbus_sink_t *sink, const ctrlbus_poll_base_cmd_answer_t *a)
{
    put_checked(sink, ctrlbus_poll_base_cmd_answer_size(a), ctrlbus_codec_poll_base_cmd_fields, a);
}

int32_t ctrlbus_poll_base_cmd_answer_write(ctrlbus_sink_t *sink,
                                           const ctrlbus_poll_base_cmd_answer_t *a,
                                           ctrlbus_frame_type_t type)
{
    return ctrlbus_codec_write_ok(sink, ctrlbus_poll_base_cmd_answer_size(a),
                                  ctrlbus_codec_poll_base_cmd_fields, a, type);
}

/* HEALTH_GET_HEALTH */

void ctrlbus_codec_health_get_health_fields(ctrlbus_sink_t *sink, const void *answer)
{
    const ctrlbus_health_get_health_answer_t *a = answer;
    ctrlbus_sink_put_u8(sink, a->flags);
    ctrlbus_sink_put_u8(sink, a->error_count);
}

void ctrlbus_health_get_health_answer_put(ctrlbus_sink_t *sink,
                                          const ctrlbus_health_get_health_answer_t *a)
{
    put_checked(sink, fixed_size(a, CTRLBUS_HEALTH_GET_HEALTH_ANSWER_SIZE),
                ctrlbus_codec_health_get_health_fields, a);
}

int32_t ctrlbus_health_get_health_answer_write(ctrlbus_sink_t *sink,
                                               const ctrlbus_health_get_health_answer_t *a,
                                               ctrlbus_frame_type_t type)
{
    return ctrlbus_codec_write_ok(sink, fixed_size(a, CTRLBUS_HEALTH_GET_HEALTH_ANSWER_SIZE),
                                  ctrlbus_codec_health_get_health_fields, a, type);
}

/* HEALTH_GET_ERROR */

int32_t ctrlbus_health_get_error_answer_size(const ctrlbus_health_get_error_answer_t *a)
{
    /* The wire field keeps a NUL, so the message holds at most 31 characters. */
    if (a == NULL ||
        !text_ok(a->message, sizeof a->message, CTRLBUS_HEALTH_MESSAGE_LEN - 1u)) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    return CTRLBUS_HEALTH_GET_ERROR_ANSWER_SIZE;
}

void ctrlbus_codec_health_get_error_fields(ctrlbus_sink_t *sink, const void *answer)
{
    const ctrlbus_health_get_error_answer_t *a = answer;
    ctrlbus_sink_put_u32(sink, a->error_code);
    ctrlbus_sink_put_text(sink, a->message, CTRLBUS_HEALTH_MESSAGE_LEN);
}

void ctrlbus_health_get_error_answer_put(ctrlbus_sink_t *sink,
                                         const ctrlbus_health_get_error_answer_t *a)
{
    put_checked(sink, ctrlbus_health_get_error_answer_size(a),
                ctrlbus_codec_health_get_error_fields, a);
}

int32_t ctrlbus_health_get_error_answer_write(ctrlbus_sink_t *sink,
                                              const ctrlbus_health_get_error_answer_t *a,
                                              ctrlbus_frame_type_t type)
{
    return ctrlbus_codec_write_ok(sink, ctrlbus_health_get_error_answer_size(a),
                                  ctrlbus_codec_health_get_error_fields, a, type);
}

/* Empty OK answers and ERROR answers. */

int32_t ctrlbus_ok_answer_write(ctrlbus_sink_t *sink, ctrlbus_frame_type_t type)
{
    return ctrlbus_codec_write_ok(sink, 0, NULL, NULL, type);
}

int32_t ctrlbus_error_answer_write(ctrlbus_sink_t *sink, uint16_t error_code,
                                   ctrlbus_frame_type_t type)
{
    int32_t result = ctrlbus_sink_begin(sink, CTRLBUS_CMD_ERROR, CTRLBUS_ERROR_ANSWER_SIZE, type);
    if (result < 0) {
        return result;
    }
    ctrlbus_sink_put_u16(sink, error_code);
    return ctrlbus_sink_end(sink);
}

/* ---- answers: the tagged union -------------------------------------------------------------- */

static const char *const ANSWER_NAMES[] = {
    [CTRLBUS_ANSWER_OK] = "OK",         [CTRLBUS_ANSWER_ERROR] = "ERROR",
    [CTRLBUS_ANSWER_INVALID] = "INVALID", [CTRLBUS_ANSWER_SYNC] = "SYNC",
    [CTRLBUS_ANSWER_ECHO] = "ECHO",
};

const char *ctrlbus_answer_name(ctrlbus_answer_kind_t kind)
{
    return (unsigned)kind < sizeof ANSWER_NAMES / sizeof ANSWER_NAMES[0] ? ANSWER_NAMES[kind]
                                                                        : NULL;
}

/* The OK answer's layout: its size (negative: the struct cannot be encoded) and fields writer. */
static int32_t ok_layout(const ctrlbus_answer_t *a, ctrlbus_codec_put_fn *put)
{
    *put = NULL;
    if (codec_has_empty_ok(a->to)) {
        return 0;
    }
    switch (a->to) {
    case CTRLBUS_REQ_CONNECT_BASE:
        *put = ctrlbus_codec_connect_base_fields;
        return ctrlbus_connect_base_answer_size(&a->as.connect_base);
    case CTRLBUS_REQ_GET_BASE_CONF:
        *put = ctrlbus_codec_get_base_conf_fields;
        return ctrlbus_get_base_conf_answer_size(&a->as.get_base_conf);
    case CTRLBUS_REQ_GET_BASE_CONF_ADV:
        *put = ctrlbus_codec_get_base_conf_adv_fields;
        return get_base_conf_adv_size(&a->as.get_base_conf_adv);
    case CTRLBUS_REQ_GET_BASE_STATUS:
        *put = ctrlbus_codec_get_base_status_fields;
        return CTRLBUS_GET_BASE_STATUS_ANSWER_SIZE;
    case CTRLBUS_REQ_GET_BASE_MOTOR_DATA:
        *put = ctrlbus_codec_get_base_motor_data_fields;
        return CTRLBUS_GET_BASE_MOTOR_DATA_ANSWER_SIZE;
    case CTRLBUS_REQ_GET_BASE_SENSOR_DATA:
        *put = ctrlbus_codec_get_base_sensor_data_fields;
        return CTRLBUS_GET_BASE_SENSOR_DATA_ANSWER_SIZE;
    case CTRLBUS_REQ_GET_BASE_BUMPER_DATA:
        *put = ctrlbus_codec_get_base_bumper_data_fields;
        return ctrlbus_get_base_bumper_data_answer_size(&a->as.get_base_bumper_data);
    case CTRLBUS_REQ_GET_CHARGER_DATA:
        *put = ctrlbus_codec_get_charger_data_fields;
        return ctrlbus_get_charger_data_answer_size(&a->as.get_charger_data);
    case CTRLBUS_REQ_SET_V_AND_GET_DEADRECKON:
        *put = ctrlbus_codec_set_v_and_get_deadreckon_fields;
        return ctrlbus_set_v_and_get_deadreckon_answer_size(&a->as.set_v_and_get_deadreckon);
    case CTRLBUS_REQ_POLL_BASE_CMD:
        *put = ctrlbus_codec_poll_base_cmd_fields;
        return ctrlbus_poll_base_cmd_answer_size(&a->as.poll_base_cmd);
    case CTRLBUS_REQ_HEALTH_GET_HEALTH:
        *put = ctrlbus_codec_health_get_health_fields;
        return CTRLBUS_HEALTH_GET_HEALTH_ANSWER_SIZE;
    case CTRLBUS_REQ_HEALTH_GET_ERROR:
        *put = ctrlbus_codec_health_get_error_fields;
        return ctrlbus_health_get_error_answer_size(&a->as.health_get_error);
    default: return CTRLBUS_ERR_ARGUMENT; /* SYNC, ECHO, GET_AUXILIARY_ANCHOR: no OK layout */
    }
}

/* Size of an answer of any kind, and (for a non-empty OK payload) its fields writer. */
static int32_t answer_layout(const ctrlbus_answer_t *answer, ctrlbus_codec_put_fn *put)
{
    *put = NULL;
    if (answer == NULL) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    switch (answer->kind) {
    case CTRLBUS_ANSWER_OK: return ok_layout(answer, put);
    case CTRLBUS_ANSWER_ERROR: return CTRLBUS_ERROR_ANSWER_SIZE;
    case CTRLBUS_ANSWER_INVALID: return 0;
    case CTRLBUS_ANSWER_SYNC:
        return bytes_size(answer->as.sync.filler, answer->as.sync.filler_len);
    case CTRLBUS_ANSWER_ECHO: return bytes_size(answer->as.echo.data, answer->as.echo.data_len);
    default: return CTRLBUS_ERR_ARGUMENT;
    }
}

int32_t ctrlbus_answer_payload_size(const ctrlbus_answer_t *answer)
{
    ctrlbus_codec_put_fn put;
    return answer_layout(answer, &put);
}

int32_t ctrlbus_answer_write(ctrlbus_sink_t *sink, const ctrlbus_answer_t *answer,
                             ctrlbus_frame_type_t type)
{
    static const uint8_t ANSWER_CMDS[] = {
        [CTRLBUS_ANSWER_OK] = CTRLBUS_CMD_OK,          [CTRLBUS_ANSWER_ERROR] = CTRLBUS_CMD_ERROR,
        [CTRLBUS_ANSWER_INVALID] = CTRLBUS_CMD_INVALID, [CTRLBUS_ANSWER_SYNC] = CTRLBUS_CMD_SYNC,
        [CTRLBUS_ANSWER_ECHO] = CTRLBUS_CMD_ECHO,
    };
    ctrlbus_codec_put_fn put;
    int32_t size = answer_layout(answer, &put);
    if (size < 0) {
        return size;
    }
    int32_t result = ctrlbus_sink_begin(sink, ANSWER_CMDS[answer->kind], (size_t)size, type);
    if (result < 0) {
        return result;
    }
    switch (answer->kind) {
    case CTRLBUS_ANSWER_OK:
        if (put != NULL) {
            put(sink, &answer->as);
        }
        break;
    case CTRLBUS_ANSWER_ERROR: ctrlbus_sink_put_u16(sink, answer->as.error.error_code); break;
    case CTRLBUS_ANSWER_SYNC:
        ctrlbus_sink_put(sink, answer->as.sync.filler, answer->as.sync.filler_len);
        break;
    case CTRLBUS_ANSWER_ECHO:
        ctrlbus_sink_put(sink, answer->as.echo.data, answer->as.echo.data_len);
        break;
    default: break; /* INVALID: empty */
    }
    return ctrlbus_sink_end(sink);
}

int32_t ctrlbus_answer_encode(uint8_t *out, size_t out_size, const ctrlbus_answer_t *answer,
                              ctrlbus_frame_type_t type)
{
    ctrlbus_sink_t sink;
    ctrlbus_buffer_t buffer;
    int32_t result = ctrlbus_sink_init_buffer(&sink, &buffer, out, out_size);
    if (result < 0) {
        return result;
    }
    return ctrlbus_answer_write(&sink, answer, type);
}
