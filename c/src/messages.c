/* SPDX-License-Identifier: MIT */
/* Typed requests and answers, serialised field by field (see ctrlbus/messages.h). This file is a
 * base's half: decoding requests, encoding answers. The master's half (encoding requests,
 * decoding answers) is messages_master.c. */
#include "ctrlbus/messages.h"

#include "codec.h"

#include <stddef.h>

/* Where the compiler says that integers are stored little-endian (GCC, clang: every target of
 * ours), a run of integer fields goes out straight from the struct; elsewhere value by value. */
#if defined(__BYTE_ORDER__) && defined(__ORDER_LITTLE_ENDIAN__) && \
    __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__
#define CODEC_HOST_LITTLE_ENDIAN 1
#else
#define CODEC_HOST_LITTLE_ENDIAN 0
#endif

/* A position is four 32-bit words, and a run of positions a run of words. */
#define POSITION_WORDS (CTRLBUS_CONF_SLOTS * 4u)
typedef char position_is_four_words[sizeof(ctrlbus_position_t) == 16u ? 1 : -1];
/* Runs of same-type members the layouts write as one field (no padding between them). */
#define FOLLOWS(type, first, second, width) (offsetof(type, second) == offsetof(type, first) + (width))

/* Every count of a layout fits its six bits (the largest: a run of positions, a health message);
 * every offset fits a byte (checked with the layouts). */
typedef char counts_fit_six_bits
    [POSITION_WORDS < 64u && CTRLBUS_SENSOR_CHANNELS < 64u && CTRLBUS_HEALTH_MESSAGE_LEN < 64u ? 1
                                                                                              : -1];

/* `size` if a char array holds a text that can be written as a text field: a NUL ends it within
 * the array and ASCII characters come before it (every text array is one byte longer than the
 * most characters its field takes: checked below). Else CTRLBUS_ERR_ARGUMENT. */
static int32_t text_checked(const char *text, size_t array_size, int32_t size)
{
    unsigned c;
    do { /* up to the NUL or a character that is not ASCII (an array is never empty) */
        c = (unsigned char)*text++;
    } while (c - 1u < 0x7Fu && --array_size != 0u);
    return c == 0u ? size : CTRLBUS_ERR_ARGUMENT;
}
typedef char text_arrays_hold_their_field_and_a_nul
    [sizeof(((ctrlbus_connect_base_answer_t *)0)->model) == CTRLBUS_MODEL_LEN + 1u &&
             sizeof(((ctrlbus_connect_base_answer_t *)0)->firmware_version_suffix) ==
                 CTRLBUS_FIRMWARE_VERSION_SUFFIX_LEN + 1u &&
             sizeof(((ctrlbus_health_get_error_answer_t *)0)->message) == CTRLBUS_HEALTH_MESSAGE_LEN
         ? 1
         : -1];

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

/* The control-bus requests (codec.h): decoding finds a request here, encoding its code. Searched
 * in order, so the requests a Core sends every few tens of milliseconds come first (a SET_V
 * found at row 1 rather than 11 saves a base ten turns of the search per exchange). */
const ctrlbus_codec_request_layout_t ctrlbus_codec_request_layouts[CTRLBUS_CODEC_REQUEST_LAYOUTS]
    CODEC_ROM = {
    {CTRLBUS_REQ_SET_V_AND_GET_DEADRECKON, CTRLBUS_CODE_SET_V_AND_GET_DEADRECKON, 0,
     CTRLBUS_SET_V_AND_GET_DEADRECKON_REQUEST_SIZE},
    {CTRLBUS_REQ_GET_BASE_STATUS, CTRLBUS_CODE_GET_BASE_STATUS, 0, CTRLBUS_PLAIN_REQUEST_SIZE},
    {CTRLBUS_REQ_GET_BASE_SENSOR_DATA, CTRLBUS_CODE_GET_BASE_SENSOR_DATA, 0,
     CTRLBUS_PLAIN_REQUEST_SIZE},
    {CTRLBUS_REQ_GET_BASE_BUMPER_DATA, CTRLBUS_CODE_GET_BASE_BUMPER_DATA, 0,
     CTRLBUS_PLAIN_REQUEST_SIZE},
    {CTRLBUS_REQ_GET_BASE_MOTOR_DATA, CTRLBUS_CODE_GET_BASE_MOTOR_DATA, 0,
     CTRLBUS_PLAIN_REQUEST_SIZE},
    {CTRLBUS_REQ_POLL_BASE_CMD, CTRLBUS_CODE_POLL_BASE_CMD, 0, CTRLBUS_PLAIN_REQUEST_SIZE},
    {CTRLBUS_REQ_CONNECT_BASE, CTRLBUS_CODE_CONNECT_BASE, 0, CTRLBUS_CONNECT_BASE_REQUEST_SIZE},
    {CTRLBUS_REQ_GET_BASE_CONF, CTRLBUS_CODE_GET_BASE_CONF, 0, CTRLBUS_PLAIN_REQUEST_SIZE},
    {CTRLBUS_REQ_GET_BASE_CONF_ADV, CTRLBUS_CODE_GET_BASE_CONF_ADV, 0, CTRLBUS_PLAIN_REQUEST_SIZE},
    {CTRLBUS_REQ_GET_CHARGER_DATA, CTRLBUS_CODE_GET_CHARGER_DATA, 0,
     CTRLBUS_GET_CHARGER_DATA_REQUEST_SIZE},
    {CTRLBUS_REQ_GET_AUXILIARY_ANCHOR, CTRLBUS_CODE_GET_AUXILIARY_ANCHOR, 0,
     CTRLBUS_PLAIN_REQUEST_SIZE},
    {CTRLBUS_REQ_SET_BASE_MOTOR, CTRLBUS_CODE_SET_BASE_MOTOR, 0,
     CTRLBUS_SET_BASE_MOTOR_REQUEST_SIZE},
    {CTRLBUS_REQ_POLL_BASE_ANS_CMD, CTRLBUS_CODE_POLL_BASE_ANS_CMD, 0, CTRLBUS_PLAIN_REQUEST_SIZE},
    {CTRLBUS_REQ_SEND_EVENT, CTRLBUS_CODE_SEND_EVENT, 0, CTRLBUS_SEND_EVENT_REQUEST_SIZE},
    {CTRLBUS_REQ_HEALTH_GET_HEALTH, CTRLBUS_CODE_HEALTH_MGMT, CTRLBUS_HEALTH_SUB_GET_HEALTH,
     CTRLBUS_HEALTH_GET_HEALTH_REQUEST_SIZE},
    {CTRLBUS_REQ_HEALTH_GET_ERROR, CTRLBUS_CODE_HEALTH_MGMT, CTRLBUS_HEALTH_SUB_GET_ERROR,
     CTRLBUS_HEALTH_GET_ERROR_REQUEST_SIZE},
    {CTRLBUS_REQ_HEALTH_CLR_ERROR, CTRLBUS_CODE_HEALTH_MGMT, CTRLBUS_HEALTH_SUB_CLR_ERROR,
     CTRLBUS_HEALTH_CLR_ERROR_REQUEST_SIZE},
};

static int32_t supported_if(bool known)
{
    return known ? CTRLBUS_OK : CTRLBUS_ERR_UNSUPPORTED;
}

/* A CMD 0xF8 payload: the table finds the request (HEALTH_MGMT by its sub-command too), then its
 * length is checked (before any value: a wrong length with a bad value is a FORMAT error), its
 * arguments read and their values checked. The arguments are one byte or a run of 32-bit words,
 * each at the start of the request's member of out->as. */
static int32_t decode_ctrl_bus(ctrlbus_request_t *out, const uint8_t *payload, size_t len)
{
    if (len == 0) {
        return CTRLBUS_ERR_FORMAT; /* no request code at all */
    }
    bool health = payload[0] == CTRLBUS_CODE_HEALTH_MGMT;
    if (health && len < 2) {
        return CTRLBUS_ERR_FORMAT;
    }
    const ctrlbus_codec_request_layout_t *layout = ctrlbus_codec_request_layouts;
    while (CODEC_ROM_BYTE(&layout->code) != payload[0] ||
           (health && CODEC_ROM_BYTE(&layout->subcommand) != payload[1])) {
        if (++layout == ctrlbus_codec_request_layouts + CTRLBUS_CODEC_REQUEST_LAYOUTS) {
            /* An unknown HEALTH_MGMT sub-command is answered 0x8002, an unknown code 0x8000. */
            out->kind = health ? CTRLBUS_REQ_HEALTH_UNKNOWN : CTRLBUS_REQ_NONE;
            return CTRLBUS_ERR_UNSUPPORTED;
        }
    }
    out->kind = (ctrlbus_req_kind_t)CODEC_ROM_BYTE(&layout->kind);
    if (len != CODEC_ROM_BYTE(&layout->size)) {
        return CTRLBUS_ERR_FORMAT;
    }
    const uint8_t *args = payload + (health ? 2 : 1);
    size_t args_len = len - (health ? 2u : 1u);
    if (args_len == 1u) {
        *(uint8_t *)(void *)&out->as = args[0];
    }
    /* int32_t and uint32_t words alike: int32_t is two's complement by definition */
    uint32_t *words = (uint32_t *)(void *)&out->as;
    for (size_t i = 0; i < args_len / 4u; i++) {
        words[i] = codec_take_u32(&args);
    }
    switch (out->kind) {
    case CTRLBUS_REQ_CONNECT_BASE:
        return supported_if(codec_connect_version_known(out->as.connect_base.protocol_version));
    case CTRLBUS_REQ_GET_CHARGER_DATA:
        return supported_if(codec_charger_type_known(out->as.get_charger_data.data_type));
    default: return CTRLBUS_OK;
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
    case CTRLBUS_CMD_BASE_CMD:
        out->kind = CTRLBUS_REQ_BASE_CMD;
        if (len != CTRLBUS_BASE_CMD_REQUEST_SIZE) {
            return CTRLBUS_ERR_FORMAT;
        }
        out->as.base_cmd.subcommand = payload[0];
        return supported_if(codec_base_cmd_known(payload[0]));
    case CTRLBUS_CMD_CTRL_BUS: return decode_ctrl_bus(out, payload, len);
    default: return CTRLBUS_ERR_UNSUPPORTED;
    }
}

/* ---- answers: one encoder per layout -------------------------------------------------------- */

/* Each answer's fields in wire order (codec.h): the encoders below and the master's decoders
 * (messages_master.c) walk the same tables. */
/* BEGIN GENERATED layouts (make generate: from protocol/ctrlbus.json) */
typedef char ctrlbus_codec_layouts_fit_their_structs
    [offsetof(ctrlbus_connect_base_answer_t, model) < 256u &&
             FOLLOWS(ctrlbus_connect_base_answer_t, firmware_version, hardware_version, 2u) &&
             offsetof(ctrlbus_connect_base_answer_t, hardware_version) < 256u &&
             offsetof(ctrlbus_connect_base_answer_t, serial) < 256u &&
             offsetof(ctrlbus_connect_base_answer_t, firmware_version_suffix) < 256u &&
             offsetof(ctrlbus_get_base_conf_answer_t, base_type) < 256u &&
             offsetof(ctrlbus_get_base_conf_answer_t, base_radius_mm_q8) < 256u &&
             FOLLOWS(ctrlbus_get_base_conf_answer_t, motor_type, sensor_num, 1u) &&
             offsetof(ctrlbus_get_base_conf_answer_t, sensor_num) < 256u &&
             offsetof(ctrlbus_get_base_conf_answer_t, sensors) < 256u &&
             offsetof(ctrlbus_get_base_conf_answer_t, bumper_num) < 256u &&
             offsetof(ctrlbus_get_base_conf_answer_t, bumpers) < 256u &&
             FOLLOWS(ctrlbus_get_base_status_answer_t, battery_percent, power_status, 1u) &&
             offsetof(ctrlbus_get_base_status_answer_t, power_status) < 256u &&
             FOLLOWS(ctrlbus_get_base_motor_data_answer_t, left_distance_mm, right_distance_mm, 4u) &&
             offsetof(ctrlbus_get_base_motor_data_answer_t, right_distance_mm) < 256u &&
             offsetof(ctrlbus_get_base_motor_data_answer_t, status) < 256u &&
             offsetof(ctrlbus_get_base_sensor_data_answer_t, distances_mm_q16) < 256u &&
             offsetof(ctrlbus_get_base_bumper_data_answer_t, bitmap) < 256u &&
             FOLLOWS(ctrlbus_get_charger_data_answer_t, beacon_count, probe_count, 1u) &&
             offsetof(ctrlbus_get_charger_data_answer_t, probe_count) < 256u &&
             FOLLOWS(ctrlbus_set_v_and_get_deadreckon_answer_t, dx_mm_q16, dy_mm_q16, 4u) &&
             FOLLOWS(ctrlbus_set_v_and_get_deadreckon_answer_t, dy_mm_q16, dtheta_deg_q16, 4u) &&
             offsetof(ctrlbus_set_v_and_get_deadreckon_answer_t, dtheta_deg_q16) < 256u &&
             offsetof(ctrlbus_set_v_and_get_deadreckon_answer_t, status) < 256u &&
             offsetof(ctrlbus_set_v_and_get_deadreckon_answer_t, timestamp_ms) < 256u &&
             FOLLOWS(ctrlbus_health_get_health_answer_t, flags, error_count, 1u) &&
             offsetof(ctrlbus_health_get_health_answer_t, error_count) < 256u &&
             offsetof(ctrlbus_health_get_error_answer_t, error_code) < 256u &&
             offsetof(ctrlbus_health_get_error_answer_t, message) < 256u
         ? 1
         : -1];

/* CONNECT_BASE (docs/protocol.md [connect]) */
const ctrlbus_codec_field_t ctrlbus_codec_connect_base_layout[] CODEC_ROM = {
    CODEC_FIELD(ctrlbus_connect_base_answer_t, model, FIELD_TEXT, CTRLBUS_MODEL_LEN),
    CODEC_FIELD(ctrlbus_connect_base_answer_t, firmware_version, FIELD_U16, 2), /* + hardware_version */
    CODEC_FIELD(ctrlbus_connect_base_answer_t, serial, FIELD_U32, CTRLBUS_SERIAL_WORDS),
    CODEC_FIELD(ctrlbus_connect_base_answer_t, firmware_version_suffix, FIELD_TEXT, CTRLBUS_FIRMWARE_VERSION_SUFFIX_LEN),
};

/* GET_BASE_CONF (docs/protocol.md [base-conf]) */
const ctrlbus_codec_field_t ctrlbus_codec_get_base_conf_layout[] CODEC_ROM = {
    CODEC_FIELD(ctrlbus_get_base_conf_answer_t, base_type, FIELD_U8, 1),
    CODEC_FIELD(ctrlbus_get_base_conf_answer_t, base_radius_mm_q8, FIELD_U32, 1),
    CODEC_FIELD(ctrlbus_get_base_conf_answer_t, motor_type, FIELD_U8, 2), /* + sensor_num */
    CODEC_FIELD(ctrlbus_get_base_conf_answer_t, sensors, FIELD_U32, CTRLBUS_CONF_SLOTS * 4u),
    CODEC_FIELD(ctrlbus_get_base_conf_answer_t, bumper_num, FIELD_U8, 1),
    CODEC_FIELD(ctrlbus_get_base_conf_answer_t, bumpers, FIELD_U32, CTRLBUS_CONF_SLOTS * 4u),
};

/* GET_BASE_CONF_ADV (docs/protocol.md [base-conf-adv]) */
const ctrlbus_codec_field_t ctrlbus_codec_get_base_conf_adv_layout[] CODEC_ROM = {
    CODEC_FIELD_BYTES(ctrlbus_get_base_conf_adv_answer_t, blob),
};

/* GET_BASE_STATUS (docs/protocol.md [status]) */
const ctrlbus_codec_field_t ctrlbus_codec_get_base_status_layout[] CODEC_ROM = {
    CODEC_FIELD(ctrlbus_get_base_status_answer_t, battery_percent, FIELD_U8, 2), /* + power_status */
};

/* GET_BASE_MOTOR_DATA (docs/protocol.md [motor-data]) */
const ctrlbus_codec_field_t ctrlbus_codec_get_base_motor_data_layout[] CODEC_ROM = {
    CODEC_FIELD(ctrlbus_get_base_motor_data_answer_t, left_distance_mm, FIELD_U32, 2), /* + right_distance_mm */
    CODEC_FIELD(ctrlbus_get_base_motor_data_answer_t, status, FIELD_U8, 1),
};

/* GET_BASE_SENSOR_DATA (docs/protocol.md [sensor-data]) */
const ctrlbus_codec_field_t ctrlbus_codec_get_base_sensor_data_layout[] CODEC_ROM = {
    CODEC_FIELD(ctrlbus_get_base_sensor_data_answer_t, distances_mm_q16, FIELD_U32, CTRLBUS_SENSOR_CHANNELS),
};

/* GET_BASE_BUMPER_DATA (docs/protocol.md [bumper-data]) */
const ctrlbus_codec_field_t ctrlbus_codec_get_base_bumper_data_layout[] CODEC_ROM = {
    CODEC_FIELD(ctrlbus_get_base_bumper_data_answer_t, bitmap, FIELD_U32, 1),
};

/* GET_CHARGER_DATA (docs/protocol.md [charger-data]) */
const ctrlbus_codec_field_t ctrlbus_codec_get_charger_data_layout[] CODEC_ROM = {
    CODEC_FIELD(ctrlbus_get_charger_data_answer_t, beacon_count, FIELD_U8, 2), /* + probe_count */
    CODEC_FIELD_BYTES(ctrlbus_get_charger_data_answer_t, probes),
};

/* SET_V_AND_GET_DEADRECKON (docs/protocol.md [set-v]) */
const ctrlbus_codec_field_t ctrlbus_codec_set_v_and_get_deadreckon_layout[] CODEC_ROM = {
    CODEC_FIELD(ctrlbus_set_v_and_get_deadreckon_answer_t, dx_mm_q16, FIELD_U32, 3), /* + dy_mm_q16 + dtheta_deg_q16 */
    CODEC_FIELD(ctrlbus_set_v_and_get_deadreckon_answer_t, status, FIELD_U8, 1),
    CODEC_FIELD(ctrlbus_set_v_and_get_deadreckon_answer_t, timestamp_ms, FIELD_U32, 1),
};

/* HEALTH_GET_HEALTH (docs/protocol.md [health]) */
const ctrlbus_codec_field_t ctrlbus_codec_health_get_health_layout[] CODEC_ROM = {
    CODEC_FIELD(ctrlbus_health_get_health_answer_t, flags, FIELD_U8, 2), /* + error_count */
};

/* HEALTH_GET_ERROR (docs/protocol.md [health]) */
const ctrlbus_codec_field_t ctrlbus_codec_health_get_error_layout[] CODEC_ROM = {
    CODEC_FIELD(ctrlbus_health_get_error_answer_t, error_code, FIELD_U32, 1),
    CODEC_FIELD(ctrlbus_health_get_error_answer_t, message, FIELD_TEXT, CTRLBUS_HEALTH_MESSAGE_LEN),
};
/* END GENERATED layouts */

/* The one field writer: walks a layout's fields until `size` bytes are out (the size, checked
 * before, decides the optional tail fields and the short bumper form). A run of integers goes
 * out straight from the struct where the host is little-endian (one write call), value by value
 * elsewhere; text goes byte by byte (its NUL repeated once reached: zeros after it), so no
 * deeper writer is on the stack. */
void ctrlbus_codec_put_fields(ctrlbus_sink_t *sink, ctrlbus_codec_layout_t layout,
                              const void *answer, size_t size)
{
    if (layout == NULL) {
        ctrlbus_sink_emit(sink, answer, size);
        return;
    }
    for (; size > 0u; layout++) {
        const uint8_t *at = (const uint8_t *)answer + CODEC_ROM_BYTE(&layout->offset);
        uint8_t shape = CODEC_ROM_BYTE(&layout->shape);
        size_t count = (size_t)(shape >> 2);
        uint8_t kind = (uint8_t)(shape & 3u);
#if CODEC_HOST_LITTLE_ENDIAN
        if (kind == FIELD_TEXT) {
            for (; count > 0u && size > 0u; count--, size--) {
                ctrlbus_sink_emit(sink, at, 1);
                if (*at != 0u) {
                    at++; /* stays on the NUL once reached */
                }
            }
            continue;
        }
        /* A run of integers is already in wire order in memory: one call for all. */
        size_t run = count << kind;
        if (run == 0u) { /* BYTES: the rest of the payload */
            at = *(const uint8_t *const *)(const void *)at;
            run = size;
        }
        run = run < size ? run : size; /* an answer may end inside a field */
        ctrlbus_sink_emit(sink, at, run);
        size -= run;
#else
        if (count == 0u) { /* BYTES: the rest of the payload */
            ctrlbus_sink_emit(sink, *(const uint8_t *const *)(const void *)at, size);
            return;
        }
        size_t width = kind == FIELD_TEXT ? 1u : (size_t)1u << kind;
        bool text_ended = false;
        for (; count > 0u && size > 0u; count--, at += width) {
            uint32_t value = width == 4u   ? *(const uint32_t *)(const void *)at
                             : width == 2u ? *(const uint16_t *)(const void *)at
                                           : at[0];
            text_ended = text_ended || (kind == FIELD_TEXT && value == 0u);
            value = text_ended ? 0u : value; /* zeros after the text's NUL */
            uint8_t bytes[4] = {(uint8_t)(value & 0xFFu), (uint8_t)((value >> 8) & 0xFFu),
                                (uint8_t)((value >> 16) & 0xFFu), (uint8_t)(value >> 24)};
            size_t piece = width < size ? width : size; /* an answer may end inside a word */
            ctrlbus_sink_emit(sink, bytes, piece);
            size -= piece;
        }
#endif
    }
}

int32_t ctrlbus_codec_write_ok(ctrlbus_sink_t *sink, int32_t size, ctrlbus_codec_layout_t layout,
                               const void *answer, ctrlbus_frame_type_t type)
{
    if (size < 0) {
        return size;
    }
    int32_t result = ctrlbus_sink_begin(sink, CTRLBUS_CMD_OK, (size_t)size, type);
    if (result < 0) {
        return result;
    }
    ctrlbus_codec_put_fields(sink, layout, answer, (size_t)size);
    return ctrlbus_sink_end(sink);
}

/* The per-layout _put: the check, then the fields (a bad struct fails the sink's frame). */
static void put_checked(ctrlbus_sink_t *sink, int32_t size, ctrlbus_codec_layout_t layout,
                        const void *answer)
{
    if (size < 0) {
        ctrlbus_sink_fail(sink, size);
        return;
    }
    ctrlbus_codec_put_fields(sink, layout, answer, (size_t)size);
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
    if (a == NULL) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    int32_t size = text_checked(a->model, sizeof a->model, CTRLBUS_CONNECT_BASE_ANSWER_SIZE);
    if (size > 0 && a->has_firmware_version_suffix) {
        size = text_checked(a->firmware_version_suffix, sizeof a->firmware_version_suffix,
                            CTRLBUS_CONNECT_BASE_ANSWER_SIZE_WITH_SUFFIX);
    }
    return size;
}

/* GET_BASE_CONF */

int32_t ctrlbus_get_base_conf_answer_size(const ctrlbus_get_base_conf_answer_t *a)
{
    if (a == NULL || a->sensor_num > CTRLBUS_CONF_SLOTS || a->bumper_num > CTRLBUS_CONF_SLOTS) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    return CTRLBUS_GET_BASE_CONF_ANSWER_SIZE;
}

/* GET_BASE_CONF_ADV */

static int32_t ctrlbus_get_base_conf_adv_answer_size(const ctrlbus_get_base_conf_adv_answer_t *a)
{
    return a != NULL ? bytes_size(a->blob, a->blob_len) : CTRLBUS_ERR_ARGUMENT;
}

/* GET_BASE_STATUS */

/* GET_BASE_MOTOR_DATA */

/* GET_BASE_SENSOR_DATA */

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

/* GET_CHARGER_DATA */

int32_t ctrlbus_get_charger_data_answer_size(const ctrlbus_get_charger_data_answer_t *a)
{
    if (a == NULL || (a->probes == NULL && a->probe_count > 0)) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    return (int32_t)CTRLBUS_GET_CHARGER_DATA_ANSWER_MIN + a->probe_count;
}

/* SET_V_AND_GET_DEADRECKON */

int32_t ctrlbus_set_v_and_get_deadreckon_answer_size(
    const ctrlbus_set_v_and_get_deadreckon_answer_t *a)
{
    return a != NULL ? (int32_t)CTRLBUS_SET_V_AND_GET_DEADRECKON_ANSWER_SIZE_OF(a)
                     : CTRLBUS_ERR_ARGUMENT;
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

/* The wire bytes of a checked POLL_BASE_CMD answer: the command or 0xFF, then the pad. Returns
 * the answer's size as ctrlbus_poll_base_cmd_answer_size(). */
static int32_t poll_base_cmd_bytes(const ctrlbus_poll_base_cmd_answer_t *a, uint8_t bytes[2])
{
    int32_t size = ctrlbus_poll_base_cmd_answer_size(a);
    bytes[0] = size > 0 && a->has_command ? a->command : CTRLBUS_POLL_NOTHING_PENDING;
    bytes[1] = size > 0 ? a->pad : 0u;
    return size;
}

void ctrlbus_poll_base_cmd_answer_put(ctrlbus_sink_t *sink, const ctrlbus_poll_base_cmd_answer_t *a)
{
    uint8_t bytes[2];
    put_checked(sink, poll_base_cmd_bytes(a, bytes), NULL, bytes);
}

int32_t ctrlbus_poll_base_cmd_answer_write(ctrlbus_sink_t *sink,
                                           const ctrlbus_poll_base_cmd_answer_t *a,
                                           ctrlbus_frame_type_t type)
{
    uint8_t bytes[2];
    return ctrlbus_codec_write_ok(sink, poll_base_cmd_bytes(a, bytes), NULL, bytes, type);
}

/* HEALTH_GET_HEALTH */

/* HEALTH_GET_ERROR */

int32_t ctrlbus_health_get_error_answer_size(const ctrlbus_health_get_error_answer_t *a)
{
    /* The wire field keeps a NUL, so the message holds at most 31 characters. */
    return a != NULL ? text_checked(a->message, sizeof a->message,
                                    CTRLBUS_HEALTH_GET_ERROR_ANSWER_SIZE)
                     : CTRLBUS_ERR_ARGUMENT;
}

/* Each answer's public encoders (messages.h): its check (`size`, an expression of the answer `a`),
 * then its fields through its layout. */
#define ANSWER_ENCODERS(name, size)                                                                \
    void ctrlbus_##name##_answer_put(ctrlbus_sink_t *sink, const ctrlbus_##name##_answer_t *a)     \
    {                                                                                              \
        put_checked(sink, size, ctrlbus_codec_##name##_layout, a);                                 \
    }                                                                                              \
    int32_t ctrlbus_##name##_answer_write(ctrlbus_sink_t *sink, const ctrlbus_##name##_answer_t *a, \
                                          ctrlbus_frame_type_t type)                               \
    {                                                                                              \
        return ctrlbus_codec_write_ok(sink, size, ctrlbus_codec_##name##_layout, a, type);         \
    }

/* BEGIN GENERATED encoders (make generate: from protocol/ctrlbus.json) */
ANSWER_ENCODERS(connect_base, ctrlbus_connect_base_answer_size(a))
ANSWER_ENCODERS(get_base_conf, ctrlbus_get_base_conf_answer_size(a))
ANSWER_ENCODERS(get_base_conf_adv, ctrlbus_get_base_conf_adv_answer_size(a))
ANSWER_ENCODERS(get_base_status, fixed_size(a, CTRLBUS_GET_BASE_STATUS_ANSWER_SIZE))
ANSWER_ENCODERS(get_base_motor_data, fixed_size(a, CTRLBUS_GET_BASE_MOTOR_DATA_ANSWER_SIZE))
ANSWER_ENCODERS(get_base_sensor_data, fixed_size(a, CTRLBUS_GET_BASE_SENSOR_DATA_ANSWER_SIZE))
ANSWER_ENCODERS(get_base_bumper_data, ctrlbus_get_base_bumper_data_answer_size(a))
ANSWER_ENCODERS(get_charger_data, ctrlbus_get_charger_data_answer_size(a))
ANSWER_ENCODERS(set_v_and_get_deadreckon,
                a != NULL ? (int32_t)CTRLBUS_SET_V_AND_GET_DEADRECKON_ANSWER_SIZE_OF(a) : CTRLBUS_ERR_ARGUMENT)
ANSWER_ENCODERS(health_get_health, fixed_size(a, CTRLBUS_HEALTH_GET_HEALTH_ANSWER_SIZE))
ANSWER_ENCODERS(health_get_error, ctrlbus_health_get_error_answer_size(a))
/* END GENERATED encoders */

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
static int32_t ok_layout(const ctrlbus_answer_t *a, ctrlbus_codec_layout_t *layout)
{
    *layout = NULL;
    if (codec_has_empty_ok(a->to)) {
        return 0;
    }
    switch (a->to) {
    case CTRLBUS_REQ_CONNECT_BASE:
        *layout = ctrlbus_codec_connect_base_layout;
        return ctrlbus_connect_base_answer_size(&a->as.connect_base);
    case CTRLBUS_REQ_GET_BASE_CONF:
        *layout = ctrlbus_codec_get_base_conf_layout;
        return ctrlbus_get_base_conf_answer_size(&a->as.get_base_conf);
    case CTRLBUS_REQ_GET_BASE_CONF_ADV:
        *layout = ctrlbus_codec_get_base_conf_adv_layout;
        return ctrlbus_get_base_conf_adv_answer_size(&a->as.get_base_conf_adv);
    case CTRLBUS_REQ_GET_BASE_STATUS:
        *layout = ctrlbus_codec_get_base_status_layout;
        return (int32_t)CTRLBUS_GET_BASE_STATUS_ANSWER_SIZE_OF(&a->as.get_base_status);
    case CTRLBUS_REQ_GET_BASE_MOTOR_DATA:
        *layout = ctrlbus_codec_get_base_motor_data_layout;
        return (int32_t)CTRLBUS_GET_BASE_MOTOR_DATA_ANSWER_SIZE_OF(&a->as.get_base_motor_data);
    case CTRLBUS_REQ_GET_BASE_SENSOR_DATA:
        *layout = ctrlbus_codec_get_base_sensor_data_layout;
        return (int32_t)CTRLBUS_GET_BASE_SENSOR_DATA_ANSWER_SIZE_OF(&a->as.get_base_sensor_data);
    case CTRLBUS_REQ_GET_BASE_BUMPER_DATA:
        *layout = ctrlbus_codec_get_base_bumper_data_layout;
        return ctrlbus_get_base_bumper_data_answer_size(&a->as.get_base_bumper_data);
    case CTRLBUS_REQ_GET_CHARGER_DATA:
        *layout = ctrlbus_codec_get_charger_data_layout;
        return ctrlbus_get_charger_data_answer_size(&a->as.get_charger_data);
    case CTRLBUS_REQ_SET_V_AND_GET_DEADRECKON:
        *layout = ctrlbus_codec_set_v_and_get_deadreckon_layout;
        return ctrlbus_set_v_and_get_deadreckon_answer_size(&a->as.set_v_and_get_deadreckon);
    case CTRLBUS_REQ_POLL_BASE_CMD: /* written by ctrlbus_poll_base_cmd_answer_put() */
        return ctrlbus_poll_base_cmd_answer_size(&a->as.poll_base_cmd);
    case CTRLBUS_REQ_HEALTH_GET_HEALTH:
        *layout = ctrlbus_codec_health_get_health_layout;
        return (int32_t)CTRLBUS_HEALTH_GET_HEALTH_ANSWER_SIZE_OF(&a->as.health_get_health);
    case CTRLBUS_REQ_HEALTH_GET_ERROR:
        *layout = ctrlbus_codec_health_get_error_layout;
        return ctrlbus_health_get_error_answer_size(&a->as.health_get_error);
    default: return CTRLBUS_ERR_ARGUMENT; /* SYNC, ECHO, GET_AUXILIARY_ANCHOR: no OK layout */
    }
}

/* Size of an answer of any kind, and (for a non-empty OK payload) its fields writer. */
static int32_t answer_layout(const ctrlbus_answer_t *answer, ctrlbus_codec_layout_t *layout)
{
    *layout = NULL;
    if (answer == NULL) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    switch (answer->kind) {
    case CTRLBUS_ANSWER_OK: return ok_layout(answer, layout);
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
    ctrlbus_codec_layout_t layout;
    return answer_layout(answer, &layout);
}

int32_t ctrlbus_answer_write(ctrlbus_sink_t *sink, const ctrlbus_answer_t *answer,
                             ctrlbus_frame_type_t type)
{
    static const uint8_t ANSWER_CMDS[] = {
        [CTRLBUS_ANSWER_OK] = CTRLBUS_CMD_OK,          [CTRLBUS_ANSWER_ERROR] = CTRLBUS_CMD_ERROR,
        [CTRLBUS_ANSWER_INVALID] = CTRLBUS_CMD_INVALID, [CTRLBUS_ANSWER_SYNC] = CTRLBUS_CMD_SYNC,
        [CTRLBUS_ANSWER_ECHO] = CTRLBUS_CMD_ECHO,
    };
    ctrlbus_codec_layout_t layout;
    int32_t size = answer_layout(answer, &layout);
    if (size < 0) {
        return size;
    }
    int32_t result = ctrlbus_sink_begin(sink, ANSWER_CMDS[answer->kind], (size_t)size, type);
    if (result < 0) {
        return result;
    }
    switch (answer->kind) {
    case CTRLBUS_ANSWER_OK:
        if (answer->to == CTRLBUS_REQ_POLL_BASE_CMD) {
            ctrlbus_poll_base_cmd_answer_put(sink, &answer->as.poll_base_cmd);
        } else if (layout != NULL) {
            ctrlbus_codec_put_fields(sink, layout, &answer->as, (size_t)size);
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
