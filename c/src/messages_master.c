/* SPDX-License-Identifier: MIT */
/* The master's half of the message codecs (see ctrlbus/messages.h): request encoders and answer
 * decoders, what a Core, an emulator or a test tool needs and a base never does. In a file of
 * their own so that a base firmware never links them, and compiled only with
 * CTRLBUS_CONFIG_MASTER_CODECS (ctrlbus/ctrlbus_config.h). */
#include "ctrlbus/messages.h"

#if CTRLBUS_CONFIG_MASTER_CODECS

#include <string.h>

#include "codec.h"

/* ---- reading fields ------------------------------------------------------------------------- */

/* A text field of field_size bytes into out[out_size]: the ASCII characters before the first NUL,
 * NUL-terminated. FORMAT for a byte above 0x7F before the NUL, or for text that leaves no room for
 * the terminator in out (out_size == field_size means the field itself must hold a NUL). */
static int32_t take_text(const uint8_t **p, char *out, size_t out_size, size_t field_size)
{
    const uint8_t *field = *p;
    *p += field_size;
    size_t len = 0;
    while (len < field_size && field[len] != 0) {
        if (field[len] > 0x7Fu) {
            return CTRLBUS_ERR_FORMAT;
        }
        len++;
    }
    if (len >= out_size) {
        return CTRLBUS_ERR_FORMAT;
    }
    for (size_t i = 0; i < len; i++) {
        out[i] = (char)field[i];
    }
    memset(out + len, 0, out_size - len);
    return CTRLBUS_OK;
}

static void take_position(const uint8_t **p, ctrlbus_position_t *out)
{
    out->x_mm_q8 = codec_take_s32(p);
    out->y_mm_q8 = codec_take_s32(p);
    out->z_mm_q8 = codec_take_s32(p);
    out->angle_deg_q8 = codec_take_u32(p);
}

/* Common checks of every decoder: pointers, then the exact length. */
static int32_t check_decode(const void *out, const uint8_t *payload, size_t len, size_t expected)
{
    if (out == NULL || (payload == NULL && len > 0)) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    return len == expected ? CTRLBUS_OK : CTRLBUS_ERR_FORMAT;
}

/* ---- requests ------------------------------------------------------------------------------- */

static const ctrlbus_codec_request_layout_t *layout_of_kind(ctrlbus_req_kind_t kind)
{
    for (size_t i = 0; i < CTRLBUS_CODEC_REQUEST_LAYOUTS; i++) {
        if (CODEC_ROM_BYTE(&ctrlbus_codec_request_layouts[i].kind) == (uint8_t)kind) {
            return &ctrlbus_codec_request_layouts[i];
        }
    }
    return NULL;
}

int32_t ctrlbus_request_cmd(ctrlbus_req_kind_t kind)
{
    switch (kind) {
    case CTRLBUS_REQ_SYNC: return CTRLBUS_CMD_SYNC;
    case CTRLBUS_REQ_ECHO: return CTRLBUS_CMD_ECHO;
    case CTRLBUS_REQ_BASE_CMD: return CTRLBUS_CMD_BASE_CMD;
    default: return layout_of_kind(kind) != NULL ? (int32_t)CTRLBUS_CMD_CTRL_BUS : -1;
    }
}

/* Argument values the protocol defines (what decoding accepts). */
static bool request_values_supported(const ctrlbus_request_t *request)
{
    switch (request->kind) {
    case CTRLBUS_REQ_BASE_CMD: return codec_base_cmd_known(request->as.base_cmd.subcommand);
    case CTRLBUS_REQ_CONNECT_BASE:
        return codec_connect_version_known(request->as.connect_base.protocol_version);
    case CTRLBUS_REQ_GET_CHARGER_DATA:
        return codec_charger_type_known(request->as.get_charger_data.data_type);
    default: return true;
    }
}

int32_t ctrlbus_request_payload_size(const ctrlbus_request_t *request)
{
    if (request == NULL || !request_values_supported(request)) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    size_t len;
    const uint8_t *bytes;
    switch (request->kind) {
    case CTRLBUS_REQ_SYNC:
        len = request->as.sync.filler_len;
        bytes = request->as.sync.filler;
        break;
    case CTRLBUS_REQ_ECHO:
        len = request->as.echo.data_len;
        bytes = request->as.echo.data;
        break;
    case CTRLBUS_REQ_BASE_CMD: return CTRLBUS_BASE_CMD_REQUEST_SIZE;
    default: {
        const ctrlbus_codec_request_layout_t *layout = layout_of_kind(request->kind);
        return layout != NULL ? (int32_t)CODEC_ROM_BYTE(&layout->size) : CTRLBUS_ERR_ARGUMENT;
    }
    }
    if (bytes == NULL && len > 0) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    return len > CTRLBUS_LONG_PAYLOAD_MAX ? CTRLBUS_ERR_TOO_BIG : (int32_t)len;
}

static void put_request_payload(ctrlbus_sink_t *sink, const ctrlbus_request_t *request)
{
    const ctrlbus_codec_request_layout_t *layout = layout_of_kind(request->kind);
    if (layout != NULL) {
        uint8_t code = CODEC_ROM_BYTE(&layout->code);
        ctrlbus_sink_put_u8(sink, code);
        if (code == CTRLBUS_CODE_HEALTH_MGMT) {
            ctrlbus_sink_put_u8(sink, CODEC_ROM_BYTE(&layout->subcommand));
        }
    }
    switch (request->kind) {
    case CTRLBUS_REQ_SYNC:
        ctrlbus_sink_put(sink, request->as.sync.filler, request->as.sync.filler_len);
        break;
    case CTRLBUS_REQ_ECHO:
        ctrlbus_sink_put(sink, request->as.echo.data, request->as.echo.data_len);
        break;
    case CTRLBUS_REQ_BASE_CMD:
        ctrlbus_sink_put_u8(sink, request->as.base_cmd.subcommand);
        break;
    case CTRLBUS_REQ_CONNECT_BASE:
        ctrlbus_sink_put_u8(sink, request->as.connect_base.protocol_version);
        break;
    case CTRLBUS_REQ_GET_CHARGER_DATA:
        ctrlbus_sink_put_u8(sink, request->as.get_charger_data.data_type);
        break;
    case CTRLBUS_REQ_SET_BASE_MOTOR:
        for (size_t i = 0; i < CTRLBUS_MOTOR_SPEEDS; i++) {
            ctrlbus_sink_put_s32(sink, request->as.set_base_motor.speeds_mm_s[i]);
        }
        break;
    case CTRLBUS_REQ_SET_V_AND_GET_DEADRECKON:
        ctrlbus_sink_put_s32(sink, request->as.set_v_and_get_deadreckon.vx_mps_q16);
        ctrlbus_sink_put_s32(sink, request->as.set_v_and_get_deadreckon.vy_mps_q16);
        ctrlbus_sink_put_s32(sink, request->as.set_v_and_get_deadreckon.omega_radps_q16);
        break;
    case CTRLBUS_REQ_SEND_EVENT:
        ctrlbus_sink_put_u8(sink, request->as.send_event.event);
        break;
    case CTRLBUS_REQ_HEALTH_GET_ERROR:
        ctrlbus_sink_put_u8(sink, request->as.health_get_error.index);
        break;
    case CTRLBUS_REQ_HEALTH_CLR_ERROR:
        ctrlbus_sink_put_u32(sink, request->as.health_clr_error.error_code);
        break;
    default: break; /* no arguments */
    }
}

int32_t ctrlbus_request_write(ctrlbus_sink_t *sink, const ctrlbus_request_t *request,
                              ctrlbus_frame_type_t type)
{
    int32_t size = ctrlbus_request_payload_size(request);
    if (size < 0) {
        return size;
    }
    int32_t result = ctrlbus_sink_begin(sink, (uint8_t)ctrlbus_request_cmd(request->kind),
                                        (size_t)size, type);
    if (result < 0) {
        return result;
    }
    put_request_payload(sink, request);
    return ctrlbus_sink_end(sink);
}

int32_t ctrlbus_request_encode(uint8_t *out, size_t out_size, const ctrlbus_request_t *request,
                               ctrlbus_frame_type_t type)
{
    ctrlbus_sink_t sink;
    ctrlbus_buffer_t buffer;
    int32_t result = ctrlbus_sink_init_buffer(&sink, &buffer, out, out_size);
    if (result < 0) {
        return result;
    }
    return ctrlbus_request_write(&sink, request, type);
}

/* ---- answers: one decoder per layout -------------------------------------------------------- */

int32_t ctrlbus_connect_base_answer_decode(ctrlbus_connect_base_answer_t *out,
                                           const uint8_t *payload, size_t len)
{
    bool with_suffix = len == CTRLBUS_CONNECT_BASE_ANSWER_SIZE_WITH_SUFFIX;
    int32_t result = check_decode(out, payload, len,
                                  with_suffix ? CTRLBUS_CONNECT_BASE_ANSWER_SIZE_WITH_SUFFIX
                                              : CTRLBUS_CONNECT_BASE_ANSWER_SIZE);
    if (result < 0) {
        return result;
    }
    const uint8_t *p = payload;
    if (take_text(&p, out->model, sizeof out->model, CTRLBUS_MODEL_LEN) < 0) {
        return CTRLBUS_ERR_FORMAT;
    }
    out->firmware_version = codec_take_u16(&p);
    out->hardware_version = codec_take_u16(&p);
    for (size_t i = 0; i < CTRLBUS_SERIAL_WORDS; i++) {
        out->serial[i] = codec_take_u32(&p);
    }
    out->has_firmware_version_suffix = with_suffix;
    memset(out->firmware_version_suffix, 0, sizeof out->firmware_version_suffix);
    if (with_suffix) {
        return take_text(&p, out->firmware_version_suffix, sizeof out->firmware_version_suffix,
                         CTRLBUS_FIRMWARE_VERSION_SUFFIX_LEN);
    }
    return CTRLBUS_OK;
}

int32_t ctrlbus_get_base_conf_answer_decode(ctrlbus_get_base_conf_answer_t *out,
                                            const uint8_t *payload, size_t len)
{
    int32_t result = check_decode(out, payload, len, CTRLBUS_GET_BASE_CONF_ANSWER_SIZE);
    if (result < 0) {
        return result;
    }
    const uint8_t *p = payload;
    out->base_type = codec_take_u8(&p);
    out->base_radius_mm_q8 = codec_take_u32(&p);
    out->motor_type = codec_take_u8(&p);
    out->sensor_num = codec_take_u8(&p);
    for (size_t i = 0; i < CTRLBUS_CONF_SLOTS; i++) {
        take_position(&p, &out->sensors[i]);
    }
    out->bumper_num = codec_take_u8(&p);
    for (size_t i = 0; i < CTRLBUS_CONF_SLOTS; i++) {
        take_position(&p, &out->bumpers[i]);
    }
    if (out->sensor_num > CTRLBUS_CONF_SLOTS || out->bumper_num > CTRLBUS_CONF_SLOTS) {
        return CTRLBUS_ERR_FORMAT;
    }
    return CTRLBUS_OK;
}

int32_t ctrlbus_get_base_conf_adv_answer_decode(ctrlbus_get_base_conf_adv_answer_t *out,
                                                const uint8_t *payload, size_t len)
{
    int32_t result = check_decode(out, payload, len, len);
    if (result < 0) {
        return result;
    }
    out->blob = payload;
    out->blob_len = len;
    return CTRLBUS_OK;
}

int32_t ctrlbus_get_base_status_answer_decode(ctrlbus_get_base_status_answer_t *out,
                                              const uint8_t *payload, size_t len)
{
    int32_t result = check_decode(out, payload, len, CTRLBUS_GET_BASE_STATUS_ANSWER_SIZE);
    if (result < 0) {
        return result;
    }
    const uint8_t *p = payload;
    out->battery_percent = codec_take_u8(&p);
    out->power_status = codec_take_u8(&p);
    return CTRLBUS_OK;
}

int32_t ctrlbus_get_base_motor_data_answer_decode(ctrlbus_get_base_motor_data_answer_t *out,
                                                  const uint8_t *payload, size_t len)
{
    int32_t result = check_decode(out, payload, len, CTRLBUS_GET_BASE_MOTOR_DATA_ANSWER_SIZE);
    if (result < 0) {
        return result;
    }
    const uint8_t *p = payload;
    out->left_distance_mm = codec_take_s32(&p);
    out->right_distance_mm = codec_take_s32(&p);
    out->status = codec_take_u8(&p);
    return CTRLBUS_OK;
}

int32_t ctrlbus_get_base_sensor_data_answer_decode(ctrlbus_get_base_sensor_data_answer_t *out,
                                                   const uint8_t *payload, size_t len)
{
    int32_t result = check_decode(out, payload, len, CTRLBUS_GET_BASE_SENSOR_DATA_ANSWER_SIZE);
    if (result < 0) {
        return result;
    }
    const uint8_t *p = payload;
    for (size_t i = 0; i < CTRLBUS_SENSOR_CHANNELS; i++) {
        out->distances_mm_q16[i] = codec_take_u32(&p);
    }
    return CTRLBUS_OK;
}

int32_t ctrlbus_get_base_bumper_data_answer_decode(ctrlbus_get_base_bumper_data_answer_t *out,
                                                   const uint8_t *payload, size_t len)
{
    bool size_ok = len >= 1 && len <= CTRLBUS_GET_BASE_BUMPER_DATA_ANSWER_SIZE;
    int32_t result = check_decode(out, payload, len, size_ok ? len : 0);
    if (result < 0 || !size_ok) {
        return result < 0 ? result : CTRLBUS_ERR_FORMAT;
    }
    out->bitmap = 0;
    for (size_t i = 0; i < len; i++) {
        out->bitmap |= (uint32_t)payload[i] << (8u * i);
    }
    out->payload_size = (uint8_t)len;
    return CTRLBUS_OK;
}

int32_t ctrlbus_get_charger_data_answer_decode(ctrlbus_get_charger_data_answer_t *out,
                                               const uint8_t *payload, size_t len)
{
    int32_t result = check_decode(out, payload, len, len); /* pointers only */
    if (result < 0) {
        return result;
    }
    size_t expected = len >= CTRLBUS_GET_CHARGER_DATA_ANSWER_MIN
                          ? CTRLBUS_GET_CHARGER_DATA_ANSWER_MIN + payload[1]
                          : CTRLBUS_GET_CHARGER_DATA_ANSWER_MIN;
    result = check_decode(out, payload, len, expected);
    if (result < 0) {
        return result;
    }
    out->beacon_count = payload[0];
    out->probe_count = payload[1];
    out->probes = payload + CTRLBUS_GET_CHARGER_DATA_ANSWER_MIN;
    return CTRLBUS_OK;
}

int32_t ctrlbus_set_v_and_get_deadreckon_answer_decode(
    ctrlbus_set_v_and_get_deadreckon_answer_t *out, const uint8_t *payload, size_t len)
{
    bool with_timestamp = len == CTRLBUS_SET_V_AND_GET_DEADRECKON_ANSWER_SIZE_WITH_TIMESTAMP;
    int32_t result =
        check_decode(out, payload, len,
                     with_timestamp ? CTRLBUS_SET_V_AND_GET_DEADRECKON_ANSWER_SIZE_WITH_TIMESTAMP
                                    : CTRLBUS_SET_V_AND_GET_DEADRECKON_ANSWER_SIZE);
    if (result < 0) {
        return result;
    }
    const uint8_t *p = payload;
    out->dx_mm_q16 = codec_take_s32(&p);
    out->dy_mm_q16 = codec_take_s32(&p);
    out->dtheta_deg_q16 = codec_take_s32(&p);
    out->status = codec_take_u8(&p);
    out->has_timestamp_ms = with_timestamp;
    out->timestamp_ms = with_timestamp ? codec_take_u32(&p) : 0;
    return CTRLBUS_OK;
}

int32_t ctrlbus_poll_base_cmd_answer_decode(ctrlbus_poll_base_cmd_answer_t *out,
                                            const uint8_t *payload, size_t len)
{
    int32_t result = check_decode(out, payload, len, len == 0 ? 0 : CTRLBUS_POLL_BASE_CMD_ANSWER_SIZE);
    if (result < 0) {
        return result;
    }
    out->payload_size = (uint8_t)len;
    out->has_command = len > 0 && payload[0] != CTRLBUS_POLL_NOTHING_PENDING;
    out->command = out->has_command ? payload[0] : 0;
    out->pad = len > 0 ? payload[1] : 0;
    return CTRLBUS_OK;
}

int32_t ctrlbus_health_get_health_answer_decode(ctrlbus_health_get_health_answer_t *out,
                                                const uint8_t *payload, size_t len)
{
    int32_t result = check_decode(out, payload, len, CTRLBUS_HEALTH_GET_HEALTH_ANSWER_SIZE);
    if (result < 0) {
        return result;
    }
    out->flags = payload[0];
    out->error_count = payload[1];
    return CTRLBUS_OK;
}

int32_t ctrlbus_health_get_error_answer_decode(ctrlbus_health_get_error_answer_t *out,
                                               const uint8_t *payload, size_t len)
{
    int32_t result = check_decode(out, payload, len, CTRLBUS_HEALTH_GET_ERROR_ANSWER_SIZE);
    if (result < 0) {
        return result;
    }
    const uint8_t *p = payload;
    out->error_code = codec_take_u32(&p);
    return take_text(&p, out->message, sizeof out->message, CTRLBUS_HEALTH_MESSAGE_LEN);
}

/* ---- answers: the tagged union -------------------------------------------------------------- */

static bool is_request_kind(ctrlbus_req_kind_t kind)
{
    return ctrlbus_request_cmd(kind) >= 0;
}

static int32_t decode_ok(ctrlbus_answer_t *out, const uint8_t *payload, size_t len)
{
    if (codec_has_empty_ok(out->to)) {
        return len == 0 ? CTRLBUS_OK : CTRLBUS_ERR_FORMAT;
    }
    switch (out->to) {
    case CTRLBUS_REQ_CONNECT_BASE:
        return ctrlbus_connect_base_answer_decode(&out->as.connect_base, payload, len);
    case CTRLBUS_REQ_GET_BASE_CONF:
        return ctrlbus_get_base_conf_answer_decode(&out->as.get_base_conf, payload, len);
    case CTRLBUS_REQ_GET_BASE_CONF_ADV:
        return ctrlbus_get_base_conf_adv_answer_decode(&out->as.get_base_conf_adv, payload, len);
    case CTRLBUS_REQ_GET_BASE_STATUS:
        return ctrlbus_get_base_status_answer_decode(&out->as.get_base_status, payload, len);
    case CTRLBUS_REQ_GET_BASE_MOTOR_DATA:
        return ctrlbus_get_base_motor_data_answer_decode(&out->as.get_base_motor_data, payload,
                                                         len);
    case CTRLBUS_REQ_GET_BASE_SENSOR_DATA:
        return ctrlbus_get_base_sensor_data_answer_decode(&out->as.get_base_sensor_data, payload,
                                                          len);
    case CTRLBUS_REQ_GET_BASE_BUMPER_DATA:
        return ctrlbus_get_base_bumper_data_answer_decode(&out->as.get_base_bumper_data, payload,
                                                          len);
    case CTRLBUS_REQ_GET_CHARGER_DATA:
        return ctrlbus_get_charger_data_answer_decode(&out->as.get_charger_data, payload, len);
    case CTRLBUS_REQ_SET_V_AND_GET_DEADRECKON:
        return ctrlbus_set_v_and_get_deadreckon_answer_decode(&out->as.set_v_and_get_deadreckon,
                                                              payload, len);
    case CTRLBUS_REQ_POLL_BASE_CMD:
        return ctrlbus_poll_base_cmd_answer_decode(&out->as.poll_base_cmd, payload, len);
    case CTRLBUS_REQ_HEALTH_GET_HEALTH:
        return ctrlbus_health_get_health_answer_decode(&out->as.health_get_health, payload, len);
    case CTRLBUS_REQ_HEALTH_GET_ERROR:
        return ctrlbus_health_get_error_answer_decode(&out->as.health_get_error, payload, len);
    default: return CTRLBUS_ERR_UNSUPPORTED; /* SYNC, ECHO, GET_AUXILIARY_ANCHOR: no OK layout */
    }
}

int32_t ctrlbus_answer_decode(ctrlbus_answer_t *out, ctrlbus_req_kind_t to, uint8_t cmd,
                              const uint8_t *payload, size_t len)
{
    if (out == NULL || (payload == NULL && len > 0) || !is_request_kind(to)) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    out->to = to;
    switch (cmd) {
    case CTRLBUS_CMD_OK:
        out->kind = CTRLBUS_ANSWER_OK;
        return decode_ok(out, payload, len);
    case CTRLBUS_CMD_ERROR: {
        out->kind = CTRLBUS_ANSWER_ERROR;
        if (len != CTRLBUS_ERROR_ANSWER_SIZE) {
            return CTRLBUS_ERR_FORMAT;
        }
        const uint8_t *p = payload;
        out->as.error.error_code = codec_take_u16(&p);
        return CTRLBUS_OK;
    }
    case CTRLBUS_CMD_INVALID:
        out->kind = CTRLBUS_ANSWER_INVALID;
        return len == 0 ? CTRLBUS_OK : CTRLBUS_ERR_FORMAT;
    case CTRLBUS_CMD_SYNC:
        out->kind = CTRLBUS_ANSWER_SYNC;
        out->as.sync.filler = payload;
        out->as.sync.filler_len = len;
        return CTRLBUS_OK;
    case CTRLBUS_CMD_ECHO:
        out->kind = CTRLBUS_ANSWER_ECHO;
        out->as.echo.data = payload;
        out->as.echo.data_len = len;
        return CTRLBUS_OK;
    default: return CTRLBUS_ERR_UNSUPPORTED;
    }
}

#endif /* CTRLBUS_CONFIG_MASTER_CODECS */
