/* SPDX-License-Identifier: MIT */
/* Typed requests and answers, serialised field by field (see ctrlbus/messages.h). */
#include "ctrlbus/messages.h"

#include <string.h>

/* ---- reading fields ------------------------------------------------------------------------- */
/* Callers check the payload length first, so these read without bounds checks. */

static uint8_t take_u8(const uint8_t **p)
{
    uint8_t value = (*p)[0];
    *p += 1;
    return value;
}

static uint16_t take_u16(const uint8_t **p)
{
    uint16_t value = (uint16_t)((uint16_t)(*p)[0] | (uint16_t)((uint16_t)(*p)[1] << 8));
    *p += 2;
    return value;
}

static uint32_t take_u32(const uint8_t **p)
{
    const uint8_t *b = *p;
    uint32_t value = (uint32_t)b[0] | ((uint32_t)b[1] << 8) | ((uint32_t)b[2] << 16) |
                     ((uint32_t)b[3] << 24);
    *p += 4;
    return value;
}

/* Two's complement without relying on implementation-defined conversions. */
static int32_t take_s32(const uint8_t **p)
{
    uint32_t value = take_u32(p);
    if (value <= 0x7FFFFFFFu) {
        return (int32_t)value;
    }
    return (int32_t)(value - 0x80000000u) - INT32_MAX - 1;
}

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
    out->x_mm_q8 = take_s32(p);
    out->y_mm_q8 = take_s32(p);
    out->z_mm_q8 = take_s32(p);
    out->angle_deg_q8 = take_u32(p);
}

static void put_position(ctrlbus_sink_t *sink, const ctrlbus_position_t *position)
{
    ctrlbus_sink_put_s32(sink, position->x_mm_q8);
    ctrlbus_sink_put_s32(sink, position->y_mm_q8);
    ctrlbus_sink_put_s32(sink, position->z_mm_q8);
    ctrlbus_sink_put_u32(sink, position->angle_deg_q8);
}

/* Common checks of every decoder: pointers, then the exact length. */
static int32_t check_decode(const void *out, const uint8_t *payload, size_t len, size_t expected)
{
    if (out == NULL || (payload == NULL && len > 0)) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    return len == expected ? CTRLBUS_OK : CTRLBUS_ERR_FORMAT;
}

static bool put_args_ok(ctrlbus_sink_t *sink, const void *message)
{
    if (message == NULL) {
        ctrlbus_sink_fail(sink, CTRLBUS_ERR_ARGUMENT);
        return false;
    }
    return true;
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

/* The control-bus requests: how each travels in a CMD 0xF8 payload. */
typedef struct {
    uint8_t kind; /* ctrlbus_req_kind_t */
    uint8_t code;
    uint8_t subcommand; /* HEALTH_MGMT only */
    uint8_t size;       /* whole payload, code (and sub-command) included */
} ctrl_bus_layout_t;

static const ctrl_bus_layout_t CTRL_BUS_LAYOUTS[] = {
    {CTRLBUS_REQ_CONNECT_BASE, CTRLBUS_CODE_CONNECT_BASE, 0, CTRLBUS_CONNECT_BASE_REQUEST_SIZE},
    {CTRLBUS_REQ_GET_BASE_CONF, CTRLBUS_CODE_GET_BASE_CONF, 0, CTRLBUS_PLAIN_REQUEST_SIZE},
    {CTRLBUS_REQ_GET_BASE_CONF_ADV, CTRLBUS_CODE_GET_BASE_CONF_ADV, 0, CTRLBUS_PLAIN_REQUEST_SIZE},
    {CTRLBUS_REQ_GET_BASE_STATUS, CTRLBUS_CODE_GET_BASE_STATUS, 0, CTRLBUS_PLAIN_REQUEST_SIZE},
    {CTRLBUS_REQ_GET_BASE_MOTOR_DATA, CTRLBUS_CODE_GET_BASE_MOTOR_DATA, 0,
     CTRLBUS_PLAIN_REQUEST_SIZE},
    {CTRLBUS_REQ_GET_BASE_SENSOR_DATA, CTRLBUS_CODE_GET_BASE_SENSOR_DATA, 0,
     CTRLBUS_PLAIN_REQUEST_SIZE},
    {CTRLBUS_REQ_GET_BASE_BUMPER_DATA, CTRLBUS_CODE_GET_BASE_BUMPER_DATA, 0,
     CTRLBUS_PLAIN_REQUEST_SIZE},
    {CTRLBUS_REQ_GET_CHARGER_DATA, CTRLBUS_CODE_GET_CHARGER_DATA, 0,
     CTRLBUS_GET_CHARGER_DATA_REQUEST_SIZE},
    {CTRLBUS_REQ_GET_AUXILIARY_ANCHOR, CTRLBUS_CODE_GET_AUXILIARY_ANCHOR, 0,
     CTRLBUS_PLAIN_REQUEST_SIZE},
    {CTRLBUS_REQ_SET_BASE_MOTOR, CTRLBUS_CODE_SET_BASE_MOTOR, 0,
     CTRLBUS_SET_BASE_MOTOR_REQUEST_SIZE},
    {CTRLBUS_REQ_SET_V_AND_GET_DEADRECKON, CTRLBUS_CODE_SET_V_AND_GET_DEADRECKON, 0,
     CTRLBUS_SET_V_AND_GET_DEADRECKON_REQUEST_SIZE},
    {CTRLBUS_REQ_POLL_BASE_CMD, CTRLBUS_CODE_POLL_BASE_CMD, 0, CTRLBUS_PLAIN_REQUEST_SIZE},
    {CTRLBUS_REQ_POLL_BASE_ANS_CMD, CTRLBUS_CODE_POLL_BASE_ANS_CMD, 0, CTRLBUS_PLAIN_REQUEST_SIZE},
    {CTRLBUS_REQ_SEND_EVENT, CTRLBUS_CODE_SEND_EVENT, 0, CTRLBUS_SEND_EVENT_REQUEST_SIZE},
    {CTRLBUS_REQ_HEALTH_GET_HEALTH, CTRLBUS_CODE_HEALTH_MGMT, CTRLBUS_HEALTH_SUB_GET_HEALTH,
     CTRLBUS_HEALTH_GET_HEALTH_REQUEST_SIZE},
    {CTRLBUS_REQ_HEALTH_GET_ERROR, CTRLBUS_CODE_HEALTH_MGMT, CTRLBUS_HEALTH_SUB_GET_ERROR,
     CTRLBUS_HEALTH_GET_ERROR_REQUEST_SIZE},
    {CTRLBUS_REQ_HEALTH_CLR_ERROR, CTRLBUS_CODE_HEALTH_MGMT, CTRLBUS_HEALTH_SUB_CLR_ERROR,
     CTRLBUS_HEALTH_CLR_ERROR_REQUEST_SIZE},
};

#define CTRL_BUS_LAYOUT_COUNT (sizeof CTRL_BUS_LAYOUTS / sizeof CTRL_BUS_LAYOUTS[0])

static const ctrl_bus_layout_t *layout_of_kind(ctrlbus_req_kind_t kind)
{
    for (size_t i = 0; i < CTRL_BUS_LAYOUT_COUNT; i++) {
        if (CTRL_BUS_LAYOUTS[i].kind == (uint8_t)kind) {
            return &CTRL_BUS_LAYOUTS[i];
        }
    }
    return NULL;
}

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

int32_t ctrlbus_request_cmd(ctrlbus_req_kind_t kind)
{
    switch (kind) {
    case CTRLBUS_REQ_SYNC: return CTRLBUS_CMD_SYNC;
    case CTRLBUS_REQ_ECHO: return CTRLBUS_CMD_ECHO;
    case CTRLBUS_REQ_BASE_CMD: return CTRLBUS_CMD_BASE_CMD;
    default: return layout_of_kind(kind) != NULL ? (int32_t)CTRLBUS_CMD_CTRL_BUS : -1;
    }
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

/* Reads the arguments of a control-bus request whose layout and length are already checked. */
static void take_ctrl_bus_arguments(ctrlbus_request_t *out, const uint8_t *args)
{
    const uint8_t *p = args;
    switch (out->kind) {
    case CTRLBUS_REQ_CONNECT_BASE:
        out->as.connect_base.protocol_version = take_u8(&p);
        break;
    case CTRLBUS_REQ_GET_CHARGER_DATA:
        out->as.get_charger_data.data_type = take_u8(&p);
        break;
    case CTRLBUS_REQ_SET_BASE_MOTOR:
        for (size_t i = 0; i < CTRLBUS_MOTOR_SPEEDS; i++) {
            out->as.set_base_motor.speeds_mm_s[i] = take_s32(&p);
        }
        break;
    case CTRLBUS_REQ_SET_V_AND_GET_DEADRECKON:
        out->as.set_v_and_get_deadreckon.vx_mps_q16 = take_s32(&p);
        out->as.set_v_and_get_deadreckon.vy_mps_q16 = take_s32(&p);
        out->as.set_v_and_get_deadreckon.omega_radps_q16 = take_s32(&p);
        break;
    case CTRLBUS_REQ_SEND_EVENT:
        out->as.send_event.event = take_u8(&p);
        break;
    case CTRLBUS_REQ_HEALTH_GET_ERROR:
        out->as.health_get_error.index = take_u8(&p);
        break;
    case CTRLBUS_REQ_HEALTH_CLR_ERROR:
        out->as.health_clr_error.error_code = take_u32(&p);
        break;
    default: break; /* no arguments */
    }
}

/* Argument values the protocol defines; others are well-formed but unsupported (ERROR 0x8000). */
static bool request_values_supported(const ctrlbus_request_t *request)
{
    switch (request->kind) {
    case CTRLBUS_REQ_BASE_CMD:
        return request->as.base_cmd.subcommand == CTRLBUS_BASE_CMD_ENTER_DFU ||
               request->as.base_cmd.subcommand == CTRLBUS_BASE_CMD_REBOOT;
    case CTRLBUS_REQ_CONNECT_BASE:
        return request->as.connect_base.protocol_version == CTRLBUS_PROTOCOL_VERSION;
    case CTRLBUS_REQ_GET_CHARGER_DATA:
        return request->as.get_charger_data.data_type == CTRLBUS_CHARGER_DATA_BEACONS;
    default: return true;
    }
}

static int32_t decode_ctrl_bus(ctrlbus_request_t *out, const uint8_t *payload, size_t len)
{
    if (len == 0) {
        return CTRLBUS_ERR_FORMAT; /* no request code at all */
    }
    uint8_t code = payload[0];
    if (code == CTRLBUS_CODE_HEALTH_MGMT && len < 2) {
        return CTRLBUS_ERR_FORMAT; /* no sub-command */
    }
    const ctrl_bus_layout_t *layout = NULL;
    for (size_t i = 0; i < CTRL_BUS_LAYOUT_COUNT && layout == NULL; i++) {
        const ctrl_bus_layout_t *candidate = &CTRL_BUS_LAYOUTS[i];
        if (candidate->code == code &&
            (code != CTRLBUS_CODE_HEALTH_MGMT || candidate->subcommand == payload[1])) {
            layout = candidate;
        }
    }
    if (layout == NULL) {
        out->kind =
            code == CTRLBUS_CODE_HEALTH_MGMT ? CTRLBUS_REQ_HEALTH_UNKNOWN : CTRLBUS_REQ_NONE;
        return CTRLBUS_ERR_UNSUPPORTED;
    }
    out->kind = (ctrlbus_req_kind_t)layout->kind;
    if (len != layout->size) {
        return CTRLBUS_ERR_FORMAT;
    }
    take_ctrl_bus_arguments(out, payload + (code == CTRLBUS_CODE_HEALTH_MGMT ? 2 : 1));
    return request_values_supported(out) ? CTRLBUS_OK : CTRLBUS_ERR_UNSUPPORTED;
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
        return request_values_supported(out) ? CTRLBUS_OK : CTRLBUS_ERR_UNSUPPORTED;
    case CTRLBUS_CMD_CTRL_BUS: return decode_ctrl_bus(out, payload, len);
    default: return CTRLBUS_ERR_UNSUPPORTED;
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
        const ctrl_bus_layout_t *layout = layout_of_kind(request->kind);
        return layout != NULL ? (int32_t)layout->size : CTRLBUS_ERR_ARGUMENT;
    }
    }
    if (bytes == NULL && len > 0) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    return len > CTRLBUS_LONG_PAYLOAD_MAX ? CTRLBUS_ERR_TOO_BIG : (int32_t)len;
}

static void put_request_payload(ctrlbus_sink_t *sink, const ctrlbus_request_t *request)
{
    const ctrl_bus_layout_t *layout = layout_of_kind(request->kind);
    if (layout != NULL) {
        ctrlbus_sink_put_u8(sink, layout->code);
        if (layout->code == CTRLBUS_CODE_HEALTH_MGMT) {
            ctrlbus_sink_put_u8(sink, layout->subcommand);
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

/* ---- answers: one codec per layout ---------------------------------------------------------- */

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

void ctrlbus_connect_base_answer_put(ctrlbus_sink_t *sink, const ctrlbus_connect_base_answer_t *a)
{
    int32_t size = ctrlbus_connect_base_answer_size(a);
    if (size < 0) {
        ctrlbus_sink_fail(sink, size);
        return;
    }
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
    out->firmware_version = take_u16(&p);
    out->hardware_version = take_u16(&p);
    for (size_t i = 0; i < CTRLBUS_SERIAL_WORDS; i++) {
        out->serial[i] = take_u32(&p);
    }
    out->has_firmware_version_suffix = with_suffix;
    memset(out->firmware_version_suffix, 0, sizeof out->firmware_version_suffix);
    if (with_suffix) {
        return take_text(&p, out->firmware_version_suffix, sizeof out->firmware_version_suffix,
                         CTRLBUS_FIRMWARE_VERSION_SUFFIX_LEN);
    }
    return CTRLBUS_OK;
}

int32_t ctrlbus_get_base_conf_answer_size(const ctrlbus_get_base_conf_answer_t *a)
{
    if (a == NULL || a->sensor_num > CTRLBUS_CONF_SLOTS || a->bumper_num > CTRLBUS_CONF_SLOTS) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    return CTRLBUS_GET_BASE_CONF_ANSWER_SIZE;
}

void ctrlbus_get_base_conf_answer_put(ctrlbus_sink_t *sink, const ctrlbus_get_base_conf_answer_t *a)
{
    int32_t size = ctrlbus_get_base_conf_answer_size(a);
    if (size < 0) {
        ctrlbus_sink_fail(sink, size);
        return;
    }
    ctrlbus_sink_put_u8(sink, a->base_type);
    ctrlbus_sink_put_u32(sink, a->base_radius_mm_q8);
    ctrlbus_sink_put_u8(sink, a->motor_type);
    ctrlbus_sink_put_u8(sink, a->sensor_num);
    for (size_t i = 0; i < CTRLBUS_CONF_SLOTS; i++) {
        put_position(sink, &a->sensors[i]);
    }
    ctrlbus_sink_put_u8(sink, a->bumper_num);
    for (size_t i = 0; i < CTRLBUS_CONF_SLOTS; i++) {
        put_position(sink, &a->bumpers[i]);
    }
}

int32_t ctrlbus_get_base_conf_answer_decode(ctrlbus_get_base_conf_answer_t *out,
                                            const uint8_t *payload, size_t len)
{
    int32_t result = check_decode(out, payload, len, CTRLBUS_GET_BASE_CONF_ANSWER_SIZE);
    if (result < 0) {
        return result;
    }
    const uint8_t *p = payload;
    out->base_type = take_u8(&p);
    out->base_radius_mm_q8 = take_u32(&p);
    out->motor_type = take_u8(&p);
    out->sensor_num = take_u8(&p);
    for (size_t i = 0; i < CTRLBUS_CONF_SLOTS; i++) {
        take_position(&p, &out->sensors[i]);
    }
    out->bumper_num = take_u8(&p);
    for (size_t i = 0; i < CTRLBUS_CONF_SLOTS; i++) {
        take_position(&p, &out->bumpers[i]);
    }
    if (out->sensor_num > CTRLBUS_CONF_SLOTS || out->bumper_num > CTRLBUS_CONF_SLOTS) {
        return CTRLBUS_ERR_FORMAT;
    }
    return CTRLBUS_OK;
}

void ctrlbus_get_base_conf_adv_answer_put(ctrlbus_sink_t *sink,
                                          const ctrlbus_get_base_conf_adv_answer_t *a)
{
    if (put_args_ok(sink, a)) {
        ctrlbus_sink_put(sink, a->blob, a->blob_len);
    }
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

void ctrlbus_get_base_status_answer_put(ctrlbus_sink_t *sink,
                                        const ctrlbus_get_base_status_answer_t *a)
{
    if (put_args_ok(sink, a)) {
        ctrlbus_sink_put_u8(sink, a->battery_percent);
        ctrlbus_sink_put_u8(sink, a->power_status);
    }
}

int32_t ctrlbus_get_base_status_answer_decode(ctrlbus_get_base_status_answer_t *out,
                                              const uint8_t *payload, size_t len)
{
    int32_t result = check_decode(out, payload, len, CTRLBUS_GET_BASE_STATUS_ANSWER_SIZE);
    if (result < 0) {
        return result;
    }
    const uint8_t *p = payload;
    out->battery_percent = take_u8(&p);
    out->power_status = take_u8(&p);
    return CTRLBUS_OK;
}

void ctrlbus_get_base_motor_data_answer_put(ctrlbus_sink_t *sink,
                                            const ctrlbus_get_base_motor_data_answer_t *a)
{
    if (put_args_ok(sink, a)) {
        ctrlbus_sink_put_s32(sink, a->left_distance_mm);
        ctrlbus_sink_put_s32(sink, a->right_distance_mm);
        ctrlbus_sink_put_u8(sink, a->status);
    }
}

int32_t ctrlbus_get_base_motor_data_answer_decode(ctrlbus_get_base_motor_data_answer_t *out,
                                                  const uint8_t *payload, size_t len)
{
    int32_t result = check_decode(out, payload, len, CTRLBUS_GET_BASE_MOTOR_DATA_ANSWER_SIZE);
    if (result < 0) {
        return result;
    }
    const uint8_t *p = payload;
    out->left_distance_mm = take_s32(&p);
    out->right_distance_mm = take_s32(&p);
    out->status = take_u8(&p);
    return CTRLBUS_OK;
}

void ctrlbus_get_base_sensor_data_answer_put(ctrlbus_sink_t *sink,
                                             const ctrlbus_get_base_sensor_data_answer_t *a)
{
    if (!put_args_ok(sink, a)) {
        return;
    }
    for (size_t i = 0; i < CTRLBUS_SENSOR_CHANNELS; i++) {
        ctrlbus_sink_put_u32(sink, a->distances_mm_q16[i]);
    }
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
        out->distances_mm_q16[i] = take_u32(&p);
    }
    return CTRLBUS_OK;
}

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

void ctrlbus_get_base_bumper_data_answer_put(ctrlbus_sink_t *sink,
                                             const ctrlbus_get_base_bumper_data_answer_t *a)
{
    int32_t size = ctrlbus_get_base_bumper_data_answer_size(a);
    if (size < 0) {
        ctrlbus_sink_fail(sink, size);
        return;
    }
    for (int32_t i = 0; i < size; i++) {
        ctrlbus_sink_put_u8(sink, (uint8_t)((a->bitmap >> (8 * i)) & 0xFFu));
    }
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

int32_t ctrlbus_get_charger_data_answer_size(const ctrlbus_get_charger_data_answer_t *a)
{
    if (a == NULL || (a->probes == NULL && a->probe_count > 0)) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    return (int32_t)CTRLBUS_GET_CHARGER_DATA_ANSWER_MIN + a->probe_count;
}

void ctrlbus_get_charger_data_answer_put(ctrlbus_sink_t *sink,
                                         const ctrlbus_get_charger_data_answer_t *a)
{
    int32_t size = ctrlbus_get_charger_data_answer_size(a);
    if (size < 0) {
        ctrlbus_sink_fail(sink, size);
        return;
    }
    ctrlbus_sink_put_u8(sink, a->beacon_count);
    ctrlbus_sink_put_u8(sink, a->probe_count);
    ctrlbus_sink_put(sink, a->probes, a->probe_count);
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

int32_t ctrlbus_set_v_and_get_deadreckon_answer_size(
    const ctrlbus_set_v_and_get_deadreckon_answer_t *a)
{
    if (a == NULL) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    return a->has_timestamp_ms ? CTRLBUS_SET_V_AND_GET_DEADRECKON_ANSWER_SIZE_WITH_TIMESTAMP
                               : CTRLBUS_SET_V_AND_GET_DEADRECKON_ANSWER_SIZE;
}

void ctrlbus_set_v_and_get_deadreckon_answer_put(
    ctrlbus_sink_t *sink, const ctrlbus_set_v_and_get_deadreckon_answer_t *a)
{
    if (!put_args_ok(sink, a)) {
        return;
    }
    ctrlbus_sink_put_s32(sink, a->dx_mm_q16);
    ctrlbus_sink_put_s32(sink, a->dy_mm_q16);
    ctrlbus_sink_put_s32(sink, a->dtheta_deg_q16);
    ctrlbus_sink_put_u8(sink, a->status);
    if (a->has_timestamp_ms) {
        ctrlbus_sink_put_u32(sink, a->timestamp_ms);
    }
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
    out->dx_mm_q16 = take_s32(&p);
    out->dy_mm_q16 = take_s32(&p);
    out->dtheta_deg_q16 = take_s32(&p);
    out->status = take_u8(&p);
    out->has_timestamp_ms = with_timestamp;
    out->timestamp_ms = with_timestamp ? take_u32(&p) : 0;
    return CTRLBUS_OK;
}

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

void ctrlbus_poll_base_cmd_answer_put(ctrlbus_sink_t *sink, const ctrlbus_poll_base_cmd_answer_t *a)
{
    int32_t size = ctrlbus_poll_base_cmd_answer_size(a);
    if (size < 0) {
        ctrlbus_sink_fail(sink, size);
        return;
    }
    if (size > 0) {
        ctrlbus_sink_put_u8(sink, a->has_command ? a->command : CTRLBUS_POLL_NOTHING_PENDING);
        ctrlbus_sink_put_u8(sink, a->pad);
    }
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

void ctrlbus_health_get_health_answer_put(ctrlbus_sink_t *sink,
                                          const ctrlbus_health_get_health_answer_t *a)
{
    if (put_args_ok(sink, a)) {
        ctrlbus_sink_put_u8(sink, a->flags);
        ctrlbus_sink_put_u8(sink, a->error_count);
    }
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

int32_t ctrlbus_health_get_error_answer_size(const ctrlbus_health_get_error_answer_t *a)
{
    /* The wire field keeps a NUL, so the message holds at most 31 characters. */
    if (a == NULL ||
        !text_ok(a->message, sizeof a->message, CTRLBUS_HEALTH_MESSAGE_LEN - 1u)) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    return CTRLBUS_HEALTH_GET_ERROR_ANSWER_SIZE;
}

void ctrlbus_health_get_error_answer_put(ctrlbus_sink_t *sink,
                                         const ctrlbus_health_get_error_answer_t *a)
{
    int32_t size = ctrlbus_health_get_error_answer_size(a);
    if (size < 0) {
        ctrlbus_sink_fail(sink, size);
        return;
    }
    ctrlbus_sink_put_u32(sink, a->error_code);
    ctrlbus_sink_put_text(sink, a->message, CTRLBUS_HEALTH_MESSAGE_LEN);
}

int32_t ctrlbus_health_get_error_answer_decode(ctrlbus_health_get_error_answer_t *out,
                                               const uint8_t *payload, size_t len)
{
    int32_t result = check_decode(out, payload, len, CTRLBUS_HEALTH_GET_ERROR_ANSWER_SIZE);
    if (result < 0) {
        return result;
    }
    const uint8_t *p = payload;
    out->error_code = take_u32(&p);
    return take_text(&p, out->message, sizeof out->message, CTRLBUS_HEALTH_MESSAGE_LEN);
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

/* Requests whose OK answer has an empty payload. */
static bool has_empty_ok(ctrlbus_req_kind_t kind)
{
    return kind == CTRLBUS_REQ_SET_BASE_MOTOR || kind == CTRLBUS_REQ_POLL_BASE_ANS_CMD ||
           kind == CTRLBUS_REQ_SEND_EVENT || kind == CTRLBUS_REQ_HEALTH_CLR_ERROR ||
           kind == CTRLBUS_REQ_BASE_CMD;
}

static bool is_request_kind(ctrlbus_req_kind_t kind)
{
    return ctrlbus_request_cmd(kind) >= 0;
}

static int32_t decode_ok(ctrlbus_answer_t *out, const uint8_t *payload, size_t len)
{
    if (has_empty_ok(out->to)) {
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
        out->as.error.error_code = take_u16(&p);
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

static int32_t bytes_size(const uint8_t *bytes, size_t len)
{
    if (bytes == NULL && len > 0) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    return len > CTRLBUS_LONG_PAYLOAD_MAX ? CTRLBUS_ERR_TOO_BIG : (int32_t)len;
}

static int32_t ok_payload_size(const ctrlbus_answer_t *a)
{
    if (has_empty_ok(a->to)) {
        return 0;
    }
    switch (a->to) {
    case CTRLBUS_REQ_CONNECT_BASE: return ctrlbus_connect_base_answer_size(&a->as.connect_base);
    case CTRLBUS_REQ_GET_BASE_CONF: return ctrlbus_get_base_conf_answer_size(&a->as.get_base_conf);
    case CTRLBUS_REQ_GET_BASE_CONF_ADV:
        return bytes_size(a->as.get_base_conf_adv.blob, a->as.get_base_conf_adv.blob_len);
    case CTRLBUS_REQ_GET_BASE_STATUS: return CTRLBUS_GET_BASE_STATUS_ANSWER_SIZE;
    case CTRLBUS_REQ_GET_BASE_MOTOR_DATA: return CTRLBUS_GET_BASE_MOTOR_DATA_ANSWER_SIZE;
    case CTRLBUS_REQ_GET_BASE_SENSOR_DATA: return CTRLBUS_GET_BASE_SENSOR_DATA_ANSWER_SIZE;
    case CTRLBUS_REQ_GET_BASE_BUMPER_DATA:
        return ctrlbus_get_base_bumper_data_answer_size(&a->as.get_base_bumper_data);
    case CTRLBUS_REQ_GET_CHARGER_DATA:
        return ctrlbus_get_charger_data_answer_size(&a->as.get_charger_data);
    case CTRLBUS_REQ_SET_V_AND_GET_DEADRECKON:
        return ctrlbus_set_v_and_get_deadreckon_answer_size(&a->as.set_v_and_get_deadreckon);
    case CTRLBUS_REQ_POLL_BASE_CMD: return ctrlbus_poll_base_cmd_answer_size(&a->as.poll_base_cmd);
    case CTRLBUS_REQ_HEALTH_GET_HEALTH: return CTRLBUS_HEALTH_GET_HEALTH_ANSWER_SIZE;
    case CTRLBUS_REQ_HEALTH_GET_ERROR:
        return ctrlbus_health_get_error_answer_size(&a->as.health_get_error);
    default: return CTRLBUS_ERR_ARGUMENT;
    }
}

static void put_ok_payload(ctrlbus_sink_t *sink, const ctrlbus_answer_t *a)
{
    switch (a->to) {
    case CTRLBUS_REQ_CONNECT_BASE: ctrlbus_connect_base_answer_put(sink, &a->as.connect_base); break;
    case CTRLBUS_REQ_GET_BASE_CONF:
        ctrlbus_get_base_conf_answer_put(sink, &a->as.get_base_conf);
        break;
    case CTRLBUS_REQ_GET_BASE_CONF_ADV:
        ctrlbus_get_base_conf_adv_answer_put(sink, &a->as.get_base_conf_adv);
        break;
    case CTRLBUS_REQ_GET_BASE_STATUS:
        ctrlbus_get_base_status_answer_put(sink, &a->as.get_base_status);
        break;
    case CTRLBUS_REQ_GET_BASE_MOTOR_DATA:
        ctrlbus_get_base_motor_data_answer_put(sink, &a->as.get_base_motor_data);
        break;
    case CTRLBUS_REQ_GET_BASE_SENSOR_DATA:
        ctrlbus_get_base_sensor_data_answer_put(sink, &a->as.get_base_sensor_data);
        break;
    case CTRLBUS_REQ_GET_BASE_BUMPER_DATA:
        ctrlbus_get_base_bumper_data_answer_put(sink, &a->as.get_base_bumper_data);
        break;
    case CTRLBUS_REQ_GET_CHARGER_DATA:
        ctrlbus_get_charger_data_answer_put(sink, &a->as.get_charger_data);
        break;
    case CTRLBUS_REQ_SET_V_AND_GET_DEADRECKON:
        ctrlbus_set_v_and_get_deadreckon_answer_put(sink, &a->as.set_v_and_get_deadreckon);
        break;
    case CTRLBUS_REQ_POLL_BASE_CMD:
        ctrlbus_poll_base_cmd_answer_put(sink, &a->as.poll_base_cmd);
        break;
    case CTRLBUS_REQ_HEALTH_GET_HEALTH:
        ctrlbus_health_get_health_answer_put(sink, &a->as.health_get_health);
        break;
    case CTRLBUS_REQ_HEALTH_GET_ERROR:
        ctrlbus_health_get_error_answer_put(sink, &a->as.health_get_error);
        break;
    default: break; /* empty OK answers */
    }
}

int32_t ctrlbus_answer_payload_size(const ctrlbus_answer_t *answer)
{
    if (answer == NULL) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    switch (answer->kind) {
    case CTRLBUS_ANSWER_OK: return ok_payload_size(answer);
    case CTRLBUS_ANSWER_ERROR: return CTRLBUS_ERROR_ANSWER_SIZE;
    case CTRLBUS_ANSWER_INVALID: return 0;
    case CTRLBUS_ANSWER_SYNC:
        return bytes_size(answer->as.sync.filler, answer->as.sync.filler_len);
    case CTRLBUS_ANSWER_ECHO: return bytes_size(answer->as.echo.data, answer->as.echo.data_len);
    default: return CTRLBUS_ERR_ARGUMENT;
    }
}

int32_t ctrlbus_answer_write(ctrlbus_sink_t *sink, const ctrlbus_answer_t *answer,
                             ctrlbus_frame_type_t type)
{
    static const uint8_t ANSWER_CMDS[] = {
        [CTRLBUS_ANSWER_OK] = CTRLBUS_CMD_OK,          [CTRLBUS_ANSWER_ERROR] = CTRLBUS_CMD_ERROR,
        [CTRLBUS_ANSWER_INVALID] = CTRLBUS_CMD_INVALID, [CTRLBUS_ANSWER_SYNC] = CTRLBUS_CMD_SYNC,
        [CTRLBUS_ANSWER_ECHO] = CTRLBUS_CMD_ECHO,
    };
    int32_t size = ctrlbus_answer_payload_size(answer);
    if (size < 0) {
        return size;
    }
    int32_t result = ctrlbus_sink_begin(sink, ANSWER_CMDS[answer->kind], (size_t)size, type);
    if (result < 0) {
        return result;
    }
    switch (answer->kind) {
    case CTRLBUS_ANSWER_OK: put_ok_payload(sink, answer); break;
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
