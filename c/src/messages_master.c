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

/* An answer's fields read through its layout (codec.h): the table the encoder walks, walked the
 * other way. Integers are assembled from their little-endian bytes (any host, any alignment of
 * the payload; a word the payload ends inside is zero-padded: the short bumper forms); text is
 * copied up to its NUL and zero-filled after it, FORMAT for a byte above 0x7F before the NUL.
 * The walk ends with the payload, or at the BYTES field (the caller points it at the rest). */
static int32_t take_fields(ctrlbus_codec_layout_t layout, void *answer, const uint8_t *payload,
                           size_t len)
{
    for (; len > 0u; layout++) {
        uint8_t *at = (uint8_t *)answer + CODEC_ROM_BYTE(&layout->offset);
        uint8_t shape = CODEC_ROM_BYTE(&layout->shape);
        size_t count = (size_t)(shape >> 2);
        uint8_t kind = (uint8_t)(shape & 3u);
        if (count == 0u) {
            return CTRLBUS_OK; /* BYTES */
        }
        if (kind == FIELD_TEXT) {
            bool ended = false;
            for (; count > 0u && len > 0u; count--, len--, payload++) {
                if (!ended && *payload > 0x7Fu) {
                    return CTRLBUS_ERR_FORMAT;
                }
                ended = ended || *payload == 0u;
                *at++ = ended ? 0u : *payload;
            }
            continue;
        }
        size_t width = (size_t)1u << kind;
        for (; count > 0u && len > 0u; count--, at += width) {
            size_t piece = width < len ? width : len;
            uint32_t value = 0;
            for (size_t i = 0; i < piece; i++) {
                value |= (uint32_t)payload[i] << (8u * i);
            }
            payload += piece;
            len -= piece;
            /* int32_t members alike: a signed type may be read and written as its unsigned one */
            if (width == 4u) {
                *(uint32_t *)(void *)at = value;
            } else if (width == 2u) {
                *(uint16_t *)(void *)at = (uint16_t)value;
            } else {
                *at = (uint8_t)value;
            }
        }
    }
    return CTRLBUS_OK;
}

/* The checks every answer decoder makes (pointers, then the length its layout allows:
 * `size_ok`), then the struct cleared (fields of a shorter form read as zero) and filled. */
static int32_t take_answer(void *out, size_t out_size, ctrlbus_codec_layout_t layout,
                           const uint8_t *payload, size_t len, bool size_ok)
{
    if (out == NULL || (payload == NULL && len > 0)) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    if (!size_ok) {
        return CTRLBUS_ERR_FORMAT;
    }
    memset(out, 0, out_size);
    return take_fields(layout, out, payload, len);
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

/* BEGIN GENERATED decoders (make generate: from protocol/ctrlbus.json) */
int32_t ctrlbus_connect_base_answer_decode(ctrlbus_connect_base_answer_t *out, const uint8_t *payload,
    size_t len)
{
    bool with_firmware_version_suffix = len == CTRLBUS_CONNECT_BASE_ANSWER_SIZE_WITH_SUFFIX;
    int32_t result = take_answer(out, sizeof *out, ctrlbus_codec_connect_base_layout, payload, len,
        with_firmware_version_suffix || len == CTRLBUS_CONNECT_BASE_ANSWER_SIZE);
    if (result < 0) {
        return result;
    }
    out->has_firmware_version_suffix = with_firmware_version_suffix;
    return CTRLBUS_OK;
}

int32_t ctrlbus_get_base_conf_answer_decode(ctrlbus_get_base_conf_answer_t *out, const uint8_t *payload,
    size_t len)
{
    int32_t result = take_answer(out, sizeof *out, ctrlbus_codec_get_base_conf_layout, payload, len,
        len == CTRLBUS_GET_BASE_CONF_ANSWER_SIZE);
    if (result < 0) {
        return result;
    }
    return out->sensor_num > 8u || out->bumper_num > 8u ? CTRLBUS_ERR_FORMAT : CTRLBUS_OK;
}

int32_t ctrlbus_get_base_conf_adv_answer_decode(ctrlbus_get_base_conf_adv_answer_t *out, const uint8_t *payload,
    size_t len)
{
    int32_t result = take_answer(out, sizeof *out, ctrlbus_codec_get_base_conf_adv_layout, payload, len,
        true);
    if (result < 0) {
        return result;
    }
    out->blob = payload;
    out->blob_len = len;
    return CTRLBUS_OK;
}

int32_t ctrlbus_get_base_status_answer_decode(ctrlbus_get_base_status_answer_t *out, const uint8_t *payload,
    size_t len)
{
    int32_t result = take_answer(out, sizeof *out, ctrlbus_codec_get_base_status_layout, payload, len,
        len == CTRLBUS_GET_BASE_STATUS_ANSWER_SIZE);
    return result;
}

int32_t ctrlbus_get_base_motor_data_answer_decode(ctrlbus_get_base_motor_data_answer_t *out, const uint8_t *payload,
    size_t len)
{
    int32_t result = take_answer(out, sizeof *out, ctrlbus_codec_get_base_motor_data_layout, payload, len,
        len == CTRLBUS_GET_BASE_MOTOR_DATA_ANSWER_SIZE);
    return result;
}

int32_t ctrlbus_get_base_sensor_data_answer_decode(ctrlbus_get_base_sensor_data_answer_t *out, const uint8_t *payload,
    size_t len)
{
    int32_t result = take_answer(out, sizeof *out, ctrlbus_codec_get_base_sensor_data_layout, payload, len,
        len == CTRLBUS_GET_BASE_SENSOR_DATA_ANSWER_SIZE);
    return result;
}

int32_t ctrlbus_get_base_bumper_data_answer_decode(ctrlbus_get_base_bumper_data_answer_t *out, const uint8_t *payload,
    size_t len)
{
    int32_t result = take_answer(out, sizeof *out, ctrlbus_codec_get_base_bumper_data_layout, payload, len,
        len >= 1u && len <= CTRLBUS_GET_BASE_BUMPER_DATA_ANSWER_SIZE);
    if (result < 0) {
        return result;
    }
    out->payload_size = (uint8_t)len;
    return CTRLBUS_OK;
}

int32_t ctrlbus_get_charger_data_answer_decode(ctrlbus_get_charger_data_answer_t *out, const uint8_t *payload,
    size_t len)
{
    int32_t result = take_answer(out, sizeof *out, ctrlbus_codec_get_charger_data_layout, payload, len,
        payload != NULL && len >= CTRLBUS_GET_CHARGER_DATA_ANSWER_MIN && len == CTRLBUS_GET_CHARGER_DATA_ANSWER_MIN + payload[1]);
    if (result < 0) {
        return result;
    }
    out->probes = payload + CTRLBUS_GET_CHARGER_DATA_ANSWER_MIN;
    return CTRLBUS_OK;
}

int32_t ctrlbus_set_v_and_get_deadreckon_answer_decode(ctrlbus_set_v_and_get_deadreckon_answer_t *out, const uint8_t *payload,
    size_t len)
{
    bool with_timestamp_ms = len == CTRLBUS_SET_V_AND_GET_DEADRECKON_ANSWER_SIZE_WITH_TIMESTAMP;
    int32_t result = take_answer(out, sizeof *out, ctrlbus_codec_set_v_and_get_deadreckon_layout, payload, len,
        with_timestamp_ms || len == CTRLBUS_SET_V_AND_GET_DEADRECKON_ANSWER_SIZE);
    if (result < 0) {
        return result;
    }
    out->has_timestamp_ms = with_timestamp_ms;
    return CTRLBUS_OK;
}

int32_t ctrlbus_health_get_health_answer_decode(ctrlbus_health_get_health_answer_t *out, const uint8_t *payload,
    size_t len)
{
    int32_t result = take_answer(out, sizeof *out, ctrlbus_codec_health_get_health_layout, payload, len,
        len == CTRLBUS_HEALTH_GET_HEALTH_ANSWER_SIZE);
    return result;
}

int32_t ctrlbus_health_get_error_answer_decode(ctrlbus_health_get_error_answer_t *out, const uint8_t *payload,
    size_t len)
{
    int32_t result = take_answer(out, sizeof *out, ctrlbus_codec_health_get_error_layout, payload, len,
        len == CTRLBUS_HEALTH_GET_ERROR_ANSWER_SIZE);
    if (result < 0) {
        return result;
    }
    return out->message[CTRLBUS_HEALTH_MESSAGE_LEN - 1u] != '\0' ? CTRLBUS_ERR_FORMAT : CTRLBUS_OK;
}
/* END GENERATED decoders */

/* POLL_BASE_CMD: three forms (messages.h), no layout. */
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
