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

/* How an answer is decoded, beside its layout (the generated DECODINGS below): the payload sizes
 * its forms allow, the members its length sets, the checks after its fields. Offsets are of the
 * answer struct; NONE where there is no such member. */
#define NONE 0xFFu
typedef enum {
    DECODE_EXACT,   /* short_size or long_size (the optional tail field's form) */
    DECODE_UP_TO,   /* short_size..long_size: the last word cut short (the bumper forms) */
    DECODE_COUNTED, /* short_size + the count in the byte before the BYTES field */
    DECODE_ANY      /* any length: a BYTES field only */
} ctrlbus_codec_sizing_t;

typedef struct {
    ctrlbus_codec_layout_t layout;
    uint16_t out_size;
    uint16_t short_size;
    uint16_t long_size;
    uint8_t sizing;      /* ctrlbus_codec_sizing_t */
    uint8_t length_at;   /* a bool: the long form was sent (EXACT), or a uint8_t: the length (UP_TO) */
    uint8_t rest_at;     /* the BYTES field's pointer: the payload after the fields; for DECODE_ANY
                          * its size_t length follows it */
    uint8_t limit_max;   /* what the bytes at limit_at may hold at most (else FORMAT) */
    uint8_t limit_at[2];
} ctrlbus_codec_decoding_t;

static bool size_allowed(const ctrlbus_codec_decoding_t *how, const uint8_t *payload, size_t len)
{
    switch (how->sizing) {
    case DECODE_EXACT: return len == how->short_size || len == how->long_size;
    case DECODE_UP_TO: return len >= how->short_size && len <= how->long_size;
    case DECODE_COUNTED:
        return len >= how->short_size && len == how->short_size + payload[how->short_size - 1u];
    default: return true;
    }
}

/* Every answer decoder: pointers checked, then the length its forms allow, then the struct cleared
 * (fields of a shorter form read as zero), filled through its layout, and checked. */
static int32_t take_answer(const ctrlbus_codec_decoding_t *how, void *out, const uint8_t *payload,
                           size_t len)
{
    if (out == NULL || (payload == NULL && len > 0)) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    if (!size_allowed(how, payload, len)) {
        return CTRLBUS_ERR_FORMAT;
    }
    memset(out, 0, how->out_size);
    int32_t result = take_fields(how->layout, out, payload, len);
    uint8_t *bytes = (uint8_t *)out;
    if (how->length_at != NONE) {
        bool long_form = len == how->long_size;
        bytes[how->length_at] = (uint8_t)(how->sizing == DECODE_UP_TO ? len : (size_t)long_form);
    }
    if (how->rest_at != NONE && payload != NULL) {
        *(const uint8_t **)(void *)(bytes + how->rest_at) = payload + how->short_size;
    }
    if (how->sizing == DECODE_ANY) {
        *(size_t *)(void *)(bytes + how->rest_at + sizeof(const uint8_t *)) = len;
    }
    for (size_t i = 0; i < 2u && result == CTRLBUS_OK; i++) {
        if (how->limit_at[i] != NONE && bytes[how->limit_at[i]] > how->limit_max) {
            result = CTRLBUS_ERR_FORMAT;
        }
    }
    return result;
}

/* A public answer decoder (messages.h): its answer's row of DECODINGS. */
#define ANSWER_DECODER(name, row)                                                                  \
    int32_t ctrlbus_##name##_answer_decode(ctrlbus_##name##_answer_t *out, const uint8_t *payload, \
                                           size_t len)                                             \
    {                                                                                              \
        return take_answer(&DECODINGS[row], out, payload, len);                                    \
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
enum {
    DECODING_CONNECT_BASE,
    DECODING_GET_BASE_CONF,
    DECODING_GET_BASE_CONF_ADV,
    DECODING_GET_BASE_STATUS,
    DECODING_GET_BASE_MOTOR_DATA,
    DECODING_GET_BASE_SENSOR_DATA,
    DECODING_GET_BASE_BUMPER_DATA,
    DECODING_GET_CHARGER_DATA,
    DECODING_SET_V_AND_GET_DEADRECKON,
    DECODING_HEALTH_GET_HEALTH,
    DECODING_HEALTH_GET_ERROR
};

/* Every offset of a decoding fits its byte (NONE, 0xFF, is none). */
typedef char decoding_offsets_fit_a_byte
    [offsetof(ctrlbus_connect_base_answer_t, has_firmware_version_suffix) < NONE &&
             offsetof(ctrlbus_get_base_conf_answer_t, sensor_num) < NONE &&
             offsetof(ctrlbus_get_base_conf_answer_t, bumper_num) < NONE &&
             offsetof(ctrlbus_get_base_conf_adv_answer_t, blob) < NONE &&
             offsetof(ctrlbus_get_base_conf_adv_answer_t, blob_len) == offsetof(ctrlbus_get_base_conf_adv_answer_t, blob) + sizeof(const uint8_t *) &&
             offsetof(ctrlbus_get_base_bumper_data_answer_t, payload_size) < NONE &&
             offsetof(ctrlbus_get_charger_data_answer_t, probes) < NONE &&
             offsetof(ctrlbus_set_v_and_get_deadreckon_answer_t, has_timestamp_ms) < NONE &&
             offsetof(ctrlbus_health_get_error_answer_t, message) + CTRLBUS_HEALTH_MESSAGE_LEN - 1u < NONE ? 1 : -1];

static const ctrlbus_codec_decoding_t DECODINGS[] = {
    [DECODING_CONNECT_BASE] =
        {
            .layout = ctrlbus_codec_connect_base_layout,
            .out_size = sizeof(ctrlbus_connect_base_answer_t),
            .short_size = CTRLBUS_CONNECT_BASE_ANSWER_SIZE,
            .long_size = CTRLBUS_CONNECT_BASE_ANSWER_SIZE_WITH_SUFFIX,
            .sizing = DECODE_EXACT,
            .length_at = offsetof(ctrlbus_connect_base_answer_t, has_firmware_version_suffix),
            .rest_at = NONE,
            .limit_max = 0u,
            .limit_at = {NONE, NONE},
        },
    [DECODING_GET_BASE_CONF] =
        {
            .layout = ctrlbus_codec_get_base_conf_layout,
            .out_size = sizeof(ctrlbus_get_base_conf_answer_t),
            .short_size = CTRLBUS_GET_BASE_CONF_ANSWER_SIZE,
            .long_size = CTRLBUS_GET_BASE_CONF_ANSWER_SIZE,
            .sizing = DECODE_EXACT,
            .length_at = NONE,
            .rest_at = NONE,
            .limit_max = 8u,
            .limit_at = {offsetof(ctrlbus_get_base_conf_answer_t, sensor_num),
                         offsetof(ctrlbus_get_base_conf_answer_t, bumper_num)},
        },
    [DECODING_GET_BASE_CONF_ADV] =
        {
            .layout = ctrlbus_codec_get_base_conf_adv_layout,
            .out_size = sizeof(ctrlbus_get_base_conf_adv_answer_t),
            .short_size = 0u,
            .long_size = 0u,
            .sizing = DECODE_ANY,
            .length_at = NONE,
            .rest_at = offsetof(ctrlbus_get_base_conf_adv_answer_t, blob),
            .limit_max = 0u,
            .limit_at = {NONE, NONE},
        },
    [DECODING_GET_BASE_STATUS] =
        {
            .layout = ctrlbus_codec_get_base_status_layout,
            .out_size = sizeof(ctrlbus_get_base_status_answer_t),
            .short_size = CTRLBUS_GET_BASE_STATUS_ANSWER_SIZE,
            .long_size = CTRLBUS_GET_BASE_STATUS_ANSWER_SIZE,
            .sizing = DECODE_EXACT,
            .length_at = NONE,
            .rest_at = NONE,
            .limit_max = 0u,
            .limit_at = {NONE, NONE},
        },
    [DECODING_GET_BASE_MOTOR_DATA] =
        {
            .layout = ctrlbus_codec_get_base_motor_data_layout,
            .out_size = sizeof(ctrlbus_get_base_motor_data_answer_t),
            .short_size = CTRLBUS_GET_BASE_MOTOR_DATA_ANSWER_SIZE,
            .long_size = CTRLBUS_GET_BASE_MOTOR_DATA_ANSWER_SIZE,
            .sizing = DECODE_EXACT,
            .length_at = NONE,
            .rest_at = NONE,
            .limit_max = 0u,
            .limit_at = {NONE, NONE},
        },
    [DECODING_GET_BASE_SENSOR_DATA] =
        {
            .layout = ctrlbus_codec_get_base_sensor_data_layout,
            .out_size = sizeof(ctrlbus_get_base_sensor_data_answer_t),
            .short_size = CTRLBUS_GET_BASE_SENSOR_DATA_ANSWER_SIZE,
            .long_size = CTRLBUS_GET_BASE_SENSOR_DATA_ANSWER_SIZE,
            .sizing = DECODE_EXACT,
            .length_at = NONE,
            .rest_at = NONE,
            .limit_max = 0u,
            .limit_at = {NONE, NONE},
        },
    [DECODING_GET_BASE_BUMPER_DATA] =
        {
            .layout = ctrlbus_codec_get_base_bumper_data_layout,
            .out_size = sizeof(ctrlbus_get_base_bumper_data_answer_t),
            .short_size = 1u,
            .long_size = CTRLBUS_GET_BASE_BUMPER_DATA_ANSWER_SIZE,
            .sizing = DECODE_UP_TO,
            .length_at = offsetof(ctrlbus_get_base_bumper_data_answer_t, payload_size),
            .rest_at = NONE,
            .limit_max = 0u,
            .limit_at = {NONE, NONE},
        },
    [DECODING_GET_CHARGER_DATA] =
        {
            .layout = ctrlbus_codec_get_charger_data_layout,
            .out_size = sizeof(ctrlbus_get_charger_data_answer_t),
            .short_size = CTRLBUS_GET_CHARGER_DATA_ANSWER_MIN,
            .long_size = CTRLBUS_GET_CHARGER_DATA_ANSWER_MIN,
            .sizing = DECODE_COUNTED,
            .length_at = NONE,
            .rest_at = offsetof(ctrlbus_get_charger_data_answer_t, probes),
            .limit_max = 0u,
            .limit_at = {NONE, NONE},
        },
    [DECODING_SET_V_AND_GET_DEADRECKON] =
        {
            .layout = ctrlbus_codec_set_v_and_get_deadreckon_layout,
            .out_size = sizeof(ctrlbus_set_v_and_get_deadreckon_answer_t),
            .short_size = CTRLBUS_SET_V_AND_GET_DEADRECKON_ANSWER_SIZE,
            .long_size = CTRLBUS_SET_V_AND_GET_DEADRECKON_ANSWER_SIZE_WITH_TIMESTAMP,
            .sizing = DECODE_EXACT,
            .length_at = offsetof(ctrlbus_set_v_and_get_deadreckon_answer_t, has_timestamp_ms),
            .rest_at = NONE,
            .limit_max = 0u,
            .limit_at = {NONE, NONE},
        },
    [DECODING_HEALTH_GET_HEALTH] =
        {
            .layout = ctrlbus_codec_health_get_health_layout,
            .out_size = sizeof(ctrlbus_health_get_health_answer_t),
            .short_size = CTRLBUS_HEALTH_GET_HEALTH_ANSWER_SIZE,
            .long_size = CTRLBUS_HEALTH_GET_HEALTH_ANSWER_SIZE,
            .sizing = DECODE_EXACT,
            .length_at = NONE,
            .rest_at = NONE,
            .limit_max = 0u,
            .limit_at = {NONE, NONE},
        },
    [DECODING_HEALTH_GET_ERROR] =
        {
            .layout = ctrlbus_codec_health_get_error_layout,
            .out_size = sizeof(ctrlbus_health_get_error_answer_t),
            .short_size = CTRLBUS_HEALTH_GET_ERROR_ANSWER_SIZE,
            .long_size = CTRLBUS_HEALTH_GET_ERROR_ANSWER_SIZE,
            .sizing = DECODE_EXACT,
            .length_at = NONE,
            .rest_at = NONE,
            .limit_max = 0u,
            .limit_at = {offsetof(ctrlbus_health_get_error_answer_t, message) + CTRLBUS_HEALTH_MESSAGE_LEN - 1u,
                         NONE},
        },
};

ANSWER_DECODER(connect_base, DECODING_CONNECT_BASE)
ANSWER_DECODER(get_base_conf, DECODING_GET_BASE_CONF)
ANSWER_DECODER(get_base_conf_adv, DECODING_GET_BASE_CONF_ADV)
ANSWER_DECODER(get_base_status, DECODING_GET_BASE_STATUS)
ANSWER_DECODER(get_base_motor_data, DECODING_GET_BASE_MOTOR_DATA)
ANSWER_DECODER(get_base_sensor_data, DECODING_GET_BASE_SENSOR_DATA)
ANSWER_DECODER(get_base_bumper_data, DECODING_GET_BASE_BUMPER_DATA)
ANSWER_DECODER(get_charger_data, DECODING_GET_CHARGER_DATA)
ANSWER_DECODER(set_v_and_get_deadreckon, DECODING_SET_V_AND_GET_DEADRECKON)
ANSWER_DECODER(health_get_health, DECODING_HEALTH_GET_HEALTH)
ANSWER_DECODER(health_get_error, DECODING_HEALTH_GET_ERROR)
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
