/* SPDX-License-Identifier: MIT */
/* ctrlbus messages: typed requests and answers of the Control Bus.
 *
 * Every message is a struct whose field names are the contract's (vectors/README.md), with the
 * unit and fixed-point format in the name (_q8 / _q16: the wire integer is the value times 2^8 /
 * 2^16). Encoding writes the fields one by one into a ctrlbus_sink_t (frame.h), so the same code
 * streams an answer to a UART or fills a buffer; decoding reads them one by one from a payload.
 * Nothing is ever copied as a whole struct, so the layout in memory does not matter.
 *
 * Two levels of API:
 * - tagged unions for dispatch: ctrlbus_request_decode() turns a received frame into a
 *   ctrlbus_request_t (what a base switches on); ctrlbus_answer_decode() reads an answer knowing
 *   the request it answers; ctrlbus_request_write() / ctrlbus_answer_write() write whole frames;
 * - one codec per answer layout (ctrlbus_<name>_answer_write/_put/_decode), for a base that
 *   answers one request without building the (large) answer union. The base stack (base.h) uses
 *   neither level's entry points: it reads a request's arguments straight from the payload and
 *   writes each answer with the same layout tables as the _write functions.
 *
 * Two halves: a base decodes requests and encodes answers (src/messages.c); a master encodes
 * requests and decodes answers (src/messages_master.c, compiled and declared only with
 * CTRLBUS_CONFIG_MASTER_CODECS, on by default: see ctrlbus/ctrlbus_config.h).
 *
 * Values: decoding refuses what the protocol does not define (a wrong length, text that is not
 * ASCII, a sensor_num over 8, an unknown argument value), and encoding refuses the same values
 * with CTRLBUS_ERR_ARGUMENT, so whatever is encoded decodes again. Text fields are ASCII, NUL-padded
 * on the wire and kept up to the first NUL when decoded.
 *
 * Payload sizes: a request's payload starts with its control-bus request code (and HEALTH
 * requests with their sub-command too), and the *_REQUEST_SIZE constants include those bytes.
 * Answer sizes are those of the OK payload.
 *
 * Variable-length byte fields (SYNC filler, ECHO data, the 0x21 blob, charger probes) are a
 * pointer plus a length: a decoder points them into the payload it was given (valid as long as
 * that payload is), an encoder reads them from wherever the caller points.
 *
 * Every function here is ISR-safe (it touches only its arguments) when the sink's write callback
 * is. Decoders cost O(payload length) and never read outside payload[0..len).
 */
#ifndef CTRLBUS_MESSAGES_H
#define CTRLBUS_MESSAGES_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ctrlbus/ctrlbus.h"
#include "ctrlbus/frame.h"

#ifdef __cplusplus
extern "C" {
#endif

/* ---- wire constants ------------------------------------------------------------------------- */

/* CMD byte of requests and answers. */
#define CTRLBUS_CMD_SYNC 0x00u
#define CTRLBUS_CMD_ECHO 0x01u
#define CTRLBUS_CMD_OK 0x02u
#define CTRLBUS_CMD_ERROR 0x03u
#define CTRLBUS_CMD_CTRL_BUS 0xF8u
#define CTRLBUS_CMD_BASE_CMD 0xF9u
#define CTRLBUS_CMD_INVALID 0xFFu

/* Control-bus request codes: the first payload byte of a CMD 0xF8 frame. */
#define CTRLBUS_CODE_CONNECT_BASE 0x10u
#define CTRLBUS_CODE_GET_BASE_CONF 0x20u
#define CTRLBUS_CODE_GET_BASE_CONF_ADV 0x21u
#define CTRLBUS_CODE_GET_BASE_STATUS 0x30u
#define CTRLBUS_CODE_GET_BASE_MOTOR_DATA 0x31u
#define CTRLBUS_CODE_GET_BASE_SENSOR_DATA 0x32u
#define CTRLBUS_CODE_GET_BASE_BUMPER_DATA 0x33u
#define CTRLBUS_CODE_GET_CHARGER_DATA 0x34u
#define CTRLBUS_CODE_GET_AUXILIARY_ANCHOR 0x35u
#define CTRLBUS_CODE_SET_BASE_MOTOR 0x40u
#define CTRLBUS_CODE_SET_V_AND_GET_DEADRECKON 0x41u
#define CTRLBUS_CODE_POLL_BASE_CMD 0x50u
#define CTRLBUS_CODE_POLL_BASE_ANS_CMD 0x5Fu
#define CTRLBUS_CODE_SEND_EVENT 0x60u
#define CTRLBUS_CODE_HEALTH_MGMT 0x90u

/* HEALTH_MGMT sub-commands (second payload byte). */
#define CTRLBUS_HEALTH_SUB_GET_HEALTH 0x01u
#define CTRLBUS_HEALTH_SUB_GET_ERROR 0x02u
#define CTRLBUS_HEALTH_SUB_CLR_ERROR 0x03u

/* BASE_CMD sub-commands. */
#define CTRLBUS_BASE_CMD_ENTER_DFU 0x01u
#define CTRLBUS_BASE_CMD_REBOOT 0x02u

/* CONNECT_BASE protocol_version, GET_CHARGER_DATA data_type. */
#define CTRLBUS_PROTOCOL_VERSION 0x01u
#define CTRLBUS_CHARGER_DATA_BEACONS 0x00u

/* ERROR answer codes (u16). */
#define CTRLBUS_WIRE_ERR_NOT_SYNCHRONISED 0x0010u  /* a byte outside any frame */
#define CTRLBUS_WIRE_ERR_TOO_LONG 0x0020u          /* request longer than the receive buffer */
#define CTRLBUS_WIRE_ERR_CHECKSUM 0x0040u          /* checksum mismatch */
#define CTRLBUS_WIRE_ERR_CHECKSUM_REFERENCE 0x00C0u /* what the reference firmware sends instead */
#define CTRLBUS_WIRE_ERR_UNSUPPORTED 0x8000u       /* unknown CMD / request / argument */
#define CTRLBUS_WIRE_ERR_FORMAT 0x8001u            /* bad request payload */
#define CTRLBUS_WIRE_ERR_OPERATION 0x8002u         /* failed to execute (also unknown HEALTH sub) */

/* BEGIN GENERATED bits (make generate: from protocol/ctrlbus.json) */
/* GET_BASE_STATUS power_status ([status]). */
#define CTRLBUS_POWER_CHARGING 0x01u /* charging */
#define CTRLBUS_POWER_DC_CONNECTED 0x02u /* DC connected */
#define CTRLBUS_POWER_ON_DOCK 0x04u /* on the dock */
#define CTRLBUS_POWER_DOCK_DETECTED 0x08u /* dock detected */
#define CTRLBUS_POWER_DOCK_CONTACTED 0x10u /* dock contacted */
#define CTRLBUS_POWER_DOCK_NEGOTIATING 0x20u /* dock negotiating */
/* status of GET_BASE_MOTOR_DATA and SET_V_AND_GET_DEADRECKON ([motor-data]). */
#define CTRLBUS_MOTOR_STALL 0x02u /* wheel stall */
#define CTRLBUS_MOTOR_TRACTION_LOST 0x04u /* traction lost */
/* HEALTH_GET_HEALTH flags, and the level byte (bits 31..24) of a health error code ([health-
 * list]). */
#define CTRLBUS_HEALTH_WARNING 0x01u /* warning */
#define CTRLBUS_HEALTH_ERROR 0x02u /* error */
#define CTRLBUS_HEALTH_FATAL 0x04u /* fatal */
/* END GENERATED bits */
#define CTRLBUS_HEALTH_CODE(level, component, type, index)                                     \
    (((uint32_t)(level) << 24) | ((uint32_t)(component) << 16) | ((uint32_t)(type) << 8) |      \
     (uint32_t)(index))
/* POLL_BASE_CMD: the first answer byte that means "nothing pending" in the 2-byte form. */
#define CTRLBUS_POLL_NOTHING_PENDING 0xFFu

/* ---- field and payload sizes ---------------------------------------------------------------- */

/* BEGIN GENERATED sizes (make generate: from protocol/ctrlbus.json) */
/* Field counts. */
#define CTRLBUS_MODEL_LEN 12u /* CONNECT_BASE model */
#define CTRLBUS_SERIAL_WORDS 3u /* CONNECT_BASE serial */
#define CTRLBUS_FIRMWARE_VERSION_SUFFIX_LEN 11u /* CONNECT_BASE firmware_version_suffix */
#define CTRLBUS_CONF_SLOTS 8u /* GET_BASE_CONF sensors */
#define CTRLBUS_SENSOR_CHANNELS 16u /* GET_BASE_SENSOR_DATA distances_mm_q16 */
#define CTRLBUS_MOTOR_SPEEDS 4u /* SET_BASE_MOTOR speeds_mm_s */
#define CTRLBUS_HEALTH_MESSAGE_LEN 32u /* HEALTH_GET_ERROR message */
/* Request payloads (CMD 0xF8: request code and sub-command included). */
#define CTRLBUS_PLAIN_REQUEST_SIZE 1u /* requests without argument: just the code */
#define CTRLBUS_BASE_CMD_REQUEST_SIZE 1u
#define CTRLBUS_CONNECT_BASE_REQUEST_SIZE 2u
#define CTRLBUS_GET_CHARGER_DATA_REQUEST_SIZE 2u
#define CTRLBUS_SET_BASE_MOTOR_REQUEST_SIZE 17u
#define CTRLBUS_SET_V_AND_GET_DEADRECKON_REQUEST_SIZE 13u
#define CTRLBUS_SEND_EVENT_REQUEST_SIZE 2u
#define CTRLBUS_HEALTH_GET_HEALTH_REQUEST_SIZE 2u
#define CTRLBUS_HEALTH_GET_ERROR_REQUEST_SIZE 3u
#define CTRLBUS_HEALTH_CLR_ERROR_REQUEST_SIZE 6u
/* OK answer payloads. Where the sources know two forms, both are accepted when decoding. */
#define CTRLBUS_CONNECT_BASE_ANSWER_SIZE 28u /* without firmware_version_suffix */
#define CTRLBUS_CONNECT_BASE_ANSWER_SIZE_WITH_SUFFIX 39u
#define CTRLBUS_GET_BASE_CONF_ANSWER_SIZE 264u
#define CTRLBUS_GET_BASE_CONF_ANSWER_SIZE_OF(answer) CTRLBUS_GET_BASE_CONF_ANSWER_SIZE
#define CTRLBUS_GET_BASE_STATUS_ANSWER_SIZE 2u
#define CTRLBUS_GET_BASE_STATUS_ANSWER_SIZE_OF(answer) CTRLBUS_GET_BASE_STATUS_ANSWER_SIZE
#define CTRLBUS_GET_BASE_MOTOR_DATA_ANSWER_SIZE 9u
#define CTRLBUS_GET_BASE_MOTOR_DATA_ANSWER_SIZE_OF(answer) CTRLBUS_GET_BASE_MOTOR_DATA_ANSWER_SIZE
#define CTRLBUS_GET_BASE_SENSOR_DATA_ANSWER_SIZE 64u
#define CTRLBUS_GET_BASE_SENSOR_DATA_ANSWER_SIZE_OF(answer) CTRLBUS_GET_BASE_SENSOR_DATA_ANSWER_SIZE
#define CTRLBUS_GET_BASE_BUMPER_DATA_ANSWER_SIZE 4u /* 1..4 accepted */
#define CTRLBUS_GET_CHARGER_DATA_ANSWER_MIN 2u /* + probe_count */
#define CTRLBUS_SET_V_AND_GET_DEADRECKON_ANSWER_SIZE 13u /* without timestamp_ms */
#define CTRLBUS_SET_V_AND_GET_DEADRECKON_ANSWER_SIZE_WITH_TIMESTAMP 17u
/* The form a ctrlbus_set_v_and_get_deadreckon_answer_t asks for (its has_timestamp_ms). */
#define CTRLBUS_SET_V_AND_GET_DEADRECKON_ANSWER_SIZE_OF(answer) \
    ((answer)->has_timestamp_ms ? CTRLBUS_SET_V_AND_GET_DEADRECKON_ANSWER_SIZE_WITH_TIMESTAMP \
                                 : CTRLBUS_SET_V_AND_GET_DEADRECKON_ANSWER_SIZE)
#define CTRLBUS_POLL_BASE_CMD_ANSWER_SIZE 2u /* or 0 */
#define CTRLBUS_HEALTH_GET_HEALTH_ANSWER_SIZE 2u
#define CTRLBUS_HEALTH_GET_HEALTH_ANSWER_SIZE_OF(answer) CTRLBUS_HEALTH_GET_HEALTH_ANSWER_SIZE
#define CTRLBUS_HEALTH_GET_ERROR_ANSWER_SIZE 36u
#define CTRLBUS_HEALTH_GET_ERROR_ANSWER_SIZE_OF(answer) CTRLBUS_HEALTH_GET_ERROR_ANSWER_SIZE
/* END GENERATED sizes */
#define CTRLBUS_ERROR_ANSWER_SIZE 2u

/* ---- requests ------------------------------------------------------------------------------- */

/* Every request the protocol defines. The names are the contract's (ctrlbus_request_name()). */
typedef enum {
    CTRLBUS_REQ_NONE = 0, /* no request: unknown CMD or request code (after a failed decode) */
    CTRLBUS_REQ_SYNC,
    CTRLBUS_REQ_ECHO,
    CTRLBUS_REQ_BASE_CMD,
    CTRLBUS_REQ_CONNECT_BASE,
    CTRLBUS_REQ_GET_BASE_CONF,
    CTRLBUS_REQ_GET_BASE_CONF_ADV,
    CTRLBUS_REQ_GET_BASE_STATUS,
    CTRLBUS_REQ_GET_BASE_MOTOR_DATA,
    CTRLBUS_REQ_GET_BASE_SENSOR_DATA,
    CTRLBUS_REQ_GET_BASE_BUMPER_DATA,
    CTRLBUS_REQ_GET_CHARGER_DATA,
    CTRLBUS_REQ_GET_AUXILIARY_ANCHOR,
    CTRLBUS_REQ_SET_BASE_MOTOR,
    CTRLBUS_REQ_SET_V_AND_GET_DEADRECKON,
    CTRLBUS_REQ_POLL_BASE_CMD,
    CTRLBUS_REQ_POLL_BASE_ANS_CMD,
    CTRLBUS_REQ_SEND_EVENT,
    CTRLBUS_REQ_HEALTH_GET_HEALTH,
    CTRLBUS_REQ_HEALTH_GET_ERROR,
    CTRLBUS_REQ_HEALTH_CLR_ERROR,
    /* Only ever left by a failed ctrlbus_request_decode(): HEALTH_MGMT with an unknown
     * sub-command, which a base answers with ERROR 0x8002 instead of 0x8000. */
    CTRLBUS_REQ_HEALTH_UNKNOWN,
    CTRLBUS_REQ_COUNT
} ctrlbus_req_kind_t;

typedef struct {
    const uint8_t *filler; /* any bytes, any length (NULL when filler_len is 0) */
    size_t filler_len;
} ctrlbus_sync_request_t;

typedef struct {
    const uint8_t *data;
    size_t data_len;
} ctrlbus_echo_request_t;

typedef struct {
    uint8_t subcommand; /* CTRLBUS_BASE_CMD_ENTER_DFU or _REBOOT (others: unsupported) */
} ctrlbus_base_cmd_request_t;

typedef struct {
    uint8_t protocol_version; /* CTRLBUS_PROTOCOL_VERSION (others: unsupported, 0x8000) */
} ctrlbus_connect_base_request_t;

typedef struct {
    uint8_t data_type; /* CTRLBUS_CHARGER_DATA_BEACONS (others: unsupported, 0x8000) */
} ctrlbus_get_charger_data_request_t;

typedef struct {
    int32_t speeds_mm_s[CTRLBUS_MOTOR_SPEEDS]; /* left, right, ignored, ignored */
} ctrlbus_set_base_motor_request_t;

typedef struct {
    int32_t vx_mps_q16;      /* forward, m/s Q16 */
    int32_t vy_mps_q16;      /* left, m/s Q16 (ignored by a differential base) */
    int32_t omega_radps_q16; /* anticlockwise, rad/s Q16 */
} ctrlbus_set_v_and_get_deadreckon_request_t;

typedef struct {
    uint8_t event; /* any code: a base answers OK to unknown ones too */
} ctrlbus_send_event_request_t;

typedef struct {
    uint8_t index; /* 0 .. error_count - 1 */
} ctrlbus_health_get_error_request_t;

typedef struct {
    uint32_t error_code;
} ctrlbus_health_clr_error_request_t;

/* A request of any kind. Fields of `as` other than the one `kind` names are unspecified. */
typedef struct {
    ctrlbus_req_kind_t kind;
    union {
        ctrlbus_sync_request_t sync;
        ctrlbus_echo_request_t echo;
        ctrlbus_base_cmd_request_t base_cmd;
        ctrlbus_connect_base_request_t connect_base;
        ctrlbus_get_charger_data_request_t get_charger_data;
        ctrlbus_set_base_motor_request_t set_base_motor;
        ctrlbus_set_v_and_get_deadreckon_request_t set_v_and_get_deadreckon;
        ctrlbus_send_event_request_t send_event;
        ctrlbus_health_get_error_request_t health_get_error;
        ctrlbus_health_clr_error_request_t health_clr_error;
    } as;
} ctrlbus_request_t;

/* Reads a received frame (cmd and payload, as ctrlbus_decoder_next() gives them) as a request.
 * Returns CTRLBUS_OK with *out filled in;
 *   CTRLBUS_ERR_FORMAT when the payload length is wrong for the request (an empty CTRL_BUS payload,
 *     or HEALTH_MGMT without a sub-command, too); out->kind then names the request if it was
 *     recognised, else CTRLBUS_REQ_NONE;
 *   CTRLBUS_ERR_UNSUPPORTED for an unknown CMD (answer CMDs included), an unknown control-bus
 *     request code (out->kind = CTRLBUS_REQ_NONE), an unknown HEALTH sub-command
 *     (out->kind = CTRLBUS_REQ_HEALTH_UNKNOWN), or a well-formed request with an argument value
 *     the protocol does not define: CONNECT_BASE version other than 1, GET_CHARGER_DATA type
 *     other than 0, BASE_CMD sub-command other than 1 or 2 (out->kind names the request);
 *   (the length is checked first: a wrong length with a bad value is a FORMAT error);
 *   CTRLBUS_ERR_ARGUMENT for a NULL out, or a NULL payload with len > 0.
 * SYNC/ECHO/0x21-style byte fields point into payload. ctrlbus_request_error_code() gives the ERROR
 * code a base answers a failure with. ISR-safe. Cost: O(len) at most (SYNC/ECHO: O(1)). */
int32_t ctrlbus_request_decode(ctrlbus_request_t *out, uint8_t cmd, const uint8_t *payload,
                               size_t len);

/* The ERROR answer code for a failed ctrlbus_request_decode() (its return value and the request
 * it left): 0x8001 for CTRLBUS_ERR_FORMAT, 0x8002 for an unknown HEALTH sub-command, 0x8000 for any
 * other failure. ISR-safe. Cost: O(1). */
uint16_t ctrlbus_request_error_code(const ctrlbus_request_t *request, int32_t error);

#if CTRLBUS_CONFIG_MASTER_CODECS /* the master side: see ctrlbus/ctrlbus_config.h */
/* The CMD byte a request travels in (0x00, 0x01, 0xF9, or 0xF8 for the control-bus requests), or
 * -1 for CTRLBUS_REQ_NONE / CTRLBUS_REQ_HEALTH_UNKNOWN / an out-of-range kind. ISR-safe. O(1). */
int32_t ctrlbus_request_cmd(ctrlbus_req_kind_t kind);
#endif

/* The contract's name of a request kind ("CONNECT_BASE", "HEALTH_GET_ERROR", "SYNC", ...), or
 * NULL for CTRLBUS_REQ_NONE, CTRLBUS_REQ_HEALTH_UNKNOWN and out-of-range kinds. ISR-safe. O(1). */
const char *ctrlbus_request_name(ctrlbus_req_kind_t kind);

#if CTRLBUS_CONFIG_MASTER_CODECS /* the master side: request encoders */
/* Payload size of a request, or CTRLBUS_ERR_ARGUMENT for a kind that cannot be sent, an argument
 * value that decoding would refuse as unsupported, or a NULL byte field with a non-zero length.
 * ISR-safe. Cost: O(1). */
int32_t ctrlbus_request_payload_size(const ctrlbus_request_t *request);

/* Writes a whole request frame through sink. Returns the frame's size or a negative error
 * (CTRLBUS_ERR_ARGUMENT as for ctrlbus_request_payload_size(), CTRLBUS_ERR_TOO_BIG for a SYNC/ECHO
 * payload over a frame's limit, or the sink's errors). ISR-safe if the sink's callback is.
 * Cost: O(payload size). */
int32_t ctrlbus_request_write(ctrlbus_sink_t *sink, const ctrlbus_request_t *request,
                              ctrlbus_frame_type_t type);

/* Encodes a whole request frame into out[0..out_size). Returns the frame's size or a negative
 * error (CTRLBUS_ERR_TOO_BIG when out is too small; nothing useful is left in out then).
 * ISR-safe. Cost: O(payload size). */
int32_t ctrlbus_request_encode(uint8_t *out, size_t out_size, const ctrlbus_request_t *request,
                               ctrlbus_frame_type_t type);
#endif

/* ---- answers -------------------------------------------------------------------------------- */

/* Text fields hold the ASCII characters up to the first NUL, plus a terminating NUL (a field
 * that keeps its NUL on the wire, like HEALTH_GET_ERROR's message, holds one character less). */
/* BEGIN GENERATED answer structs (make generate: from protocol/ctrlbus.json) */
/* CONNECT_BASE (docs/protocol.md [connect]) */
typedef struct {
    char model[CTRLBUS_MODEL_LEN + 1]; /* the reference sends "ref base" */
    uint16_t firmware_version; /* (major << 8) | minor, 0x0114 = 1.20 */
    uint16_t hardware_version;
    uint32_t serial[CTRLBUS_SERIAL_WORDS]; /* the reference sends the MCU's 96-bit unique id */
    bool has_firmware_version_suffix; /* false: the shorter form (the contract's null) */
    /* 39-byte form only; `null` in the 28-byte form */
    char firmware_version_suffix[CTRLBUS_FIRMWARE_VERSION_SUFFIX_LEN + 1];
} ctrlbus_connect_base_answer_t;

/* Where a sensor or bumper sits, relative to the robot centre, x forward, y left, z up (right-
 * handed). */
typedef struct {
    int32_t x_mm_q8;
    int32_t y_mm_q8;
    int32_t z_mm_q8;
    uint32_t angle_deg_q8;
} ctrlbus_position_t;

/* GET_BASE_CONF (docs/protocol.md [base-conf]) */
typedef struct {
    uint8_t base_type;
    uint32_t base_radius_mm_q8; /* mm, Q8 */
    uint8_t motor_type;
    uint8_t sensor_num; /* distance sensors in use, 0..8 */
    ctrlbus_position_t sensors[CTRLBUS_CONF_SLOTS]; /* unused slots zero */
    uint8_t bumper_num; /* 0..8 */
    ctrlbus_position_t bumpers[CTRLBUS_CONF_SLOTS]; /* unused slots zero */
} ctrlbus_get_base_conf_answer_t;

/* GET_BASE_CONF_ADV (docs/protocol.md [base-conf-adv]) */
typedef struct {
    const uint8_t *blob; /* opaque binary configuration, any length (§12) */
    size_t blob_len;
} ctrlbus_get_base_conf_adv_answer_t;

/* GET_BASE_STATUS (docs/protocol.md [status]) */
typedef struct {
    uint8_t battery_percent; /* %; 0..100 */
    uint8_t power_status; /* CTRLBUS_POWER_* bits */
} ctrlbus_get_base_status_answer_t;

/* GET_BASE_MOTOR_DATA (docs/protocol.md [motor-data]) */
typedef struct {
    int32_t left_distance_mm; /* mm; accumulated travel */
    int32_t right_distance_mm; /* mm; accumulated travel */
    uint8_t status; /* CTRLBUS_MOTOR_* bits */
} ctrlbus_get_base_motor_data_answer_t;

/* GET_BASE_SENSOR_DATA (docs/protocol.md [sensor-data]) */
typedef struct {
    /* mm, Q16; one per sensor slot of the configuration */
    uint32_t distances_mm_q16[CTRLBUS_SENSOR_CHANNELS];
} ctrlbus_get_base_sensor_data_answer_t;

/* GET_BASE_BUMPER_DATA (docs/protocol.md [bumper-data]) */
typedef struct {
    uint32_t bitmap; /* active low: a 0 bit means triggered; 1..4 bytes, read zero-padded */
    uint8_t payload_size; /* bytes on the wire */
} ctrlbus_get_base_bumper_data_answer_t;

/* GET_CHARGER_DATA (docs/protocol.md [charger-data]) */
typedef struct {
    uint8_t beacon_count; /* 3 */
    uint8_t probe_count; /* 3 */
    /* in the order left, main, right; each a bitmap of the dock beacons the probe sees */
    const uint8_t *probes;
} ctrlbus_get_charger_data_answer_t;

/* SET_V_AND_GET_DEADRECKON (docs/protocol.md [set-v]) */
typedef struct {
    int32_t dx_mm_q16; /* mm, Q16 */
    int32_t dy_mm_q16; /* mm, Q16 */
    int32_t dtheta_deg_q16; /* degrees, Q16; anticlockwise positive */
    uint8_t status; /* CTRLBUS_MOTOR_* bits; same bits as GET_BASE_MOTOR_DATA */
    bool has_timestamp_ms; /* false: the shorter form (the contract's null) */
    /* ms; since the base powered up (17-byte form only; `null` in the 13-byte form) */
    uint32_t timestamp_ms;
} ctrlbus_set_v_and_get_deadreckon_answer_t;

/* HEALTH_GET_HEALTH (docs/protocol.md [health]) */
typedef struct {
    uint8_t flags; /* CTRLBUS_HEALTH_* bits */
    uint8_t error_count;
} ctrlbus_health_get_health_answer_t;

/* HEALTH_GET_ERROR (docs/protocol.md [health]) */
typedef struct {
    uint32_t error_code; /* layout §10.1 */
    char message[CTRLBUS_HEALTH_MESSAGE_LEN]; /* NUL-terminated (§1.5): at most 31 characters */
} ctrlbus_health_get_error_answer_t;
/* END GENERATED answer structs */

/* The three forms: payload_size 0 (nothing pending, v4), payload_size 2 with has_command false
 * (nothing pending, 0xFF form; pad is the second byte), payload_size 2 with has_command true. */
typedef struct {
    bool has_command; /* false: the contract's null */
    uint8_t command;  /* an external command code, never 0xFF */
    uint8_t payload_size; /* 0 or 2 */
    uint8_t pad;          /* the don't-care second byte; 0 when payload_size is 0 */
} ctrlbus_poll_base_cmd_answer_t;

typedef struct {
    uint16_t error_code; /* CTRLBUS_WIRE_ERR_* */
} ctrlbus_error_answer_t;

/* Per-layout codecs: what a base uses to answer one request, without the (large) answer union.
 * - _size() (for layouts whose size or values can vary) returns the payload size, or
 *   CTRLBUS_ERR_ARGUMENT for a struct that cannot be encoded.
 * - _write() writes the whole OK answer frame (CMD 0x02) of the struct through sink: it checks
 *   the struct and computes the size once, then streams the header, each field and the checksum.
 *   Returns the frame's size; CTRLBUS_ERR_ARGUMENT for a struct that cannot be encoded, found
 *   before any byte is written; CTRLBUS_ERR_TOO_BIG for a payload over the frame type's limit (a
 *   STANDARD frame), also before any byte; or the write callback's error. This is what the base
 *   stack uses (ISR-safe if the sink's callback is; cost O(size), a few write calls per field).
 * - _put() writes the OK payload's fields into a frame the caller began with that size (or the
 *   constant above). It checks the struct too; a bad one makes ctrlbus_sink_end() return
 *   CTRLBUS_ERR_ARGUMENT, but on a streaming sink the header is already out then.
 * - _decode() (master side, CTRLBUS_CONFIG_MASTER_CODECS) reads payload[0..len) into *out
 *   (unspecified on failure) and returns CTRLBUS_OK, CTRLBUS_ERR_FORMAT for a length or value the
 *   layout does not allow, or CTRLBUS_ERR_ARGUMENT for NULL pointers.
 * ISR-safe. Cost: O(size). */

/* size/put/write fail (ARGUMENT) for text that is not ASCII. */
int32_t ctrlbus_connect_base_answer_size(const ctrlbus_connect_base_answer_t *a); /* 28 or 39 */
int32_t ctrlbus_connect_base_answer_write(ctrlbus_sink_t *sink,
                                          const ctrlbus_connect_base_answer_t *a,
                                          ctrlbus_frame_type_t type);
void ctrlbus_connect_base_answer_put(ctrlbus_sink_t *sink, const ctrlbus_connect_base_answer_t *a);

/* size/put/write fail (ARGUMENT) for a sensor_num or bumper_num over 8. */
int32_t ctrlbus_get_base_conf_answer_size(const ctrlbus_get_base_conf_answer_t *a); /* 264 */
int32_t ctrlbus_get_base_conf_answer_write(ctrlbus_sink_t *sink,
                                           const ctrlbus_get_base_conf_answer_t *a,
                                           ctrlbus_frame_type_t type);
void ctrlbus_get_base_conf_answer_put(ctrlbus_sink_t *sink, const ctrlbus_get_base_conf_answer_t *a);

/* put/write fail (ARGUMENT) for a NULL blob with a non-zero length, TOO_BIG over 65534 bytes. */
int32_t ctrlbus_get_base_conf_adv_answer_write(ctrlbus_sink_t *sink,
                                               const ctrlbus_get_base_conf_adv_answer_t *a,
                                               ctrlbus_frame_type_t type);
void ctrlbus_get_base_conf_adv_answer_put(ctrlbus_sink_t *sink,
                                          const ctrlbus_get_base_conf_adv_answer_t *a);

int32_t ctrlbus_get_base_status_answer_write(ctrlbus_sink_t *sink,
                                             const ctrlbus_get_base_status_answer_t *a,
                                             ctrlbus_frame_type_t type);
void ctrlbus_get_base_status_answer_put(ctrlbus_sink_t *sink,
                                        const ctrlbus_get_base_status_answer_t *a);

int32_t ctrlbus_get_base_motor_data_answer_write(ctrlbus_sink_t *sink,
                                                 const ctrlbus_get_base_motor_data_answer_t *a,
                                                 ctrlbus_frame_type_t type);
void ctrlbus_get_base_motor_data_answer_put(ctrlbus_sink_t *sink,
                                            const ctrlbus_get_base_motor_data_answer_t *a);

int32_t ctrlbus_get_base_sensor_data_answer_write(ctrlbus_sink_t *sink,
                                                  const ctrlbus_get_base_sensor_data_answer_t *a,
                                                  ctrlbus_frame_type_t type);
void ctrlbus_get_base_sensor_data_answer_put(ctrlbus_sink_t *sink,
                                             const ctrlbus_get_base_sensor_data_answer_t *a);

/* size/put/write fail (ARGUMENT) for a payload_size outside 1..4 or bitmap bits that do not fit
 * in it. */
int32_t ctrlbus_get_base_bumper_data_answer_size(const ctrlbus_get_base_bumper_data_answer_t *a);
int32_t ctrlbus_get_base_bumper_data_answer_write(ctrlbus_sink_t *sink,
                                                  const ctrlbus_get_base_bumper_data_answer_t *a,
                                                  ctrlbus_frame_type_t type);
void ctrlbus_get_base_bumper_data_answer_put(ctrlbus_sink_t *sink,
                                             const ctrlbus_get_base_bumper_data_answer_t *a);

/* size/put/write fail (ARGUMENT) for NULL probes with a non-zero probe_count. */
int32_t ctrlbus_get_charger_data_answer_size(const ctrlbus_get_charger_data_answer_t *a);
int32_t ctrlbus_get_charger_data_answer_write(ctrlbus_sink_t *sink,
                                              const ctrlbus_get_charger_data_answer_t *a,
                                              ctrlbus_frame_type_t type);
void ctrlbus_get_charger_data_answer_put(ctrlbus_sink_t *sink,
                                         const ctrlbus_get_charger_data_answer_t *a);

int32_t ctrlbus_set_v_and_get_deadreckon_answer_size(
    const ctrlbus_set_v_and_get_deadreckon_answer_t *a); /* 13 or 17 */
int32_t ctrlbus_set_v_and_get_deadreckon_answer_write(
    ctrlbus_sink_t *sink, const ctrlbus_set_v_and_get_deadreckon_answer_t *a,
    ctrlbus_frame_type_t type);
void ctrlbus_set_v_and_get_deadreckon_answer_put(
    ctrlbus_sink_t *sink, const ctrlbus_set_v_and_get_deadreckon_answer_t *a);

/* size/put/write fail (ARGUMENT) for a payload_size other than 0 or 2, a command with
 * payload_size 0, a pad with payload_size 0, or has_command with command 0xFF. */
int32_t ctrlbus_poll_base_cmd_answer_size(const ctrlbus_poll_base_cmd_answer_t *a);
int32_t ctrlbus_poll_base_cmd_answer_write(ctrlbus_sink_t *sink,
                                           const ctrlbus_poll_base_cmd_answer_t *a,
                                           ctrlbus_frame_type_t type);
void ctrlbus_poll_base_cmd_answer_put(ctrlbus_sink_t *sink, const ctrlbus_poll_base_cmd_answer_t *a);

int32_t ctrlbus_health_get_health_answer_write(ctrlbus_sink_t *sink,
                                               const ctrlbus_health_get_health_answer_t *a,
                                               ctrlbus_frame_type_t type);
void ctrlbus_health_get_health_answer_put(ctrlbus_sink_t *sink,
                                          const ctrlbus_health_get_health_answer_t *a);

/* size/put/write fail (ARGUMENT) for a message of 32 characters or more (no room for its NUL). */
int32_t ctrlbus_health_get_error_answer_size(const ctrlbus_health_get_error_answer_t *a); /* 36 */
int32_t ctrlbus_health_get_error_answer_write(ctrlbus_sink_t *sink,
                                              const ctrlbus_health_get_error_answer_t *a,
                                              ctrlbus_frame_type_t type);
void ctrlbus_health_get_error_answer_put(ctrlbus_sink_t *sink,
                                         const ctrlbus_health_get_error_answer_t *a);

/* Writes an OK answer frame with an empty payload (the OK of SET_BASE_MOTOR, POLL_BASE_ANS_CMD,
 * SEND_EVENT, HEALTH_CLR_ERROR, BASE_CMD). Returns its size (6 as a long frame) or a negative
 * error as ctrlbus_frame_write(). ISR-safe if the sink's callback is. Cost: O(1). */
int32_t ctrlbus_ok_answer_write(ctrlbus_sink_t *sink, ctrlbus_frame_type_t type);

/* Writes a whole ERROR answer frame (CMD 0x03, u16 code). Returns its size (7 as a long frame) or
 * a negative error as ctrlbus_frame_write(). ISR-safe if the sink's callback is. Cost: O(1). */
int32_t ctrlbus_error_answer_write(ctrlbus_sink_t *sink, uint16_t error_code,
                                   ctrlbus_frame_type_t type);

#if CTRLBUS_CONFIG_MASTER_CODECS /* the master side: answer decoders */
int32_t ctrlbus_connect_base_answer_decode(ctrlbus_connect_base_answer_t *out,
                                           const uint8_t *payload, size_t len);
int32_t ctrlbus_get_base_conf_answer_decode(ctrlbus_get_base_conf_answer_t *out,
                                            const uint8_t *payload, size_t len);
int32_t ctrlbus_get_base_conf_adv_answer_decode(ctrlbus_get_base_conf_adv_answer_t *out,
                                                const uint8_t *payload, size_t len);
int32_t ctrlbus_get_base_status_answer_decode(ctrlbus_get_base_status_answer_t *out,
                                              const uint8_t *payload, size_t len);
int32_t ctrlbus_get_base_motor_data_answer_decode(ctrlbus_get_base_motor_data_answer_t *out,
                                                  const uint8_t *payload, size_t len);
int32_t ctrlbus_get_base_sensor_data_answer_decode(ctrlbus_get_base_sensor_data_answer_t *out,
                                                   const uint8_t *payload, size_t len);
int32_t ctrlbus_get_base_bumper_data_answer_decode(ctrlbus_get_base_bumper_data_answer_t *out,
                                                   const uint8_t *payload, size_t len);
/* FORMAT unless len == 2 + probe_count. */
int32_t ctrlbus_get_charger_data_answer_decode(ctrlbus_get_charger_data_answer_t *out,
                                               const uint8_t *payload, size_t len);
int32_t ctrlbus_set_v_and_get_deadreckon_answer_decode(
    ctrlbus_set_v_and_get_deadreckon_answer_t *out, const uint8_t *payload, size_t len);
int32_t ctrlbus_poll_base_cmd_answer_decode(ctrlbus_poll_base_cmd_answer_t *out,
                                            const uint8_t *payload, size_t len);
int32_t ctrlbus_health_get_health_answer_decode(ctrlbus_health_get_health_answer_t *out,
                                                const uint8_t *payload, size_t len);
int32_t ctrlbus_health_get_error_answer_decode(ctrlbus_health_get_error_answer_t *out,
                                               const uint8_t *payload, size_t len);
#endif

/* The answer's CMD: the contract's answer names. */
typedef enum {
    CTRLBUS_ANSWER_OK = 0,   /* CMD 0x02: as.<request> per `to` (nothing for empty answers) */
    CTRLBUS_ANSWER_ERROR,    /* CMD 0x03: as.error */
    CTRLBUS_ANSWER_INVALID,  /* CMD 0xFF: empty */
    CTRLBUS_ANSWER_SYNC,     /* CMD 0x00: as.sync, the copy of the SYNC request */
    CTRLBUS_ANSWER_ECHO      /* CMD 0x01: as.echo, the copy of the ECHO request */
} ctrlbus_answer_kind_t;

/* An answer of any kind. `to` is the request it answers: an OK payload can only be read knowing
 * it. Fields of `as` other than the one that kind/to select are unspecified. */
typedef struct {
    ctrlbus_answer_kind_t kind;
    ctrlbus_req_kind_t to;
    union {
        ctrlbus_error_answer_t error;
        ctrlbus_sync_request_t sync;
        ctrlbus_echo_request_t echo;
        ctrlbus_connect_base_answer_t connect_base;
        ctrlbus_get_base_conf_answer_t get_base_conf;
        ctrlbus_get_base_conf_adv_answer_t get_base_conf_adv;
        ctrlbus_get_base_status_answer_t get_base_status;
        ctrlbus_get_base_motor_data_answer_t get_base_motor_data;
        ctrlbus_get_base_sensor_data_answer_t get_base_sensor_data;
        ctrlbus_get_base_bumper_data_answer_t get_base_bumper_data;
        ctrlbus_get_charger_data_answer_t get_charger_data;
        ctrlbus_set_v_and_get_deadreckon_answer_t set_v_and_get_deadreckon;
        ctrlbus_poll_base_cmd_answer_t poll_base_cmd;
        ctrlbus_health_get_health_answer_t health_get_health;
        ctrlbus_health_get_error_answer_t health_get_error;
    } as;
} ctrlbus_answer_t;

#if CTRLBUS_CONFIG_MASTER_CODECS /* the master side: answer decoder */
/* Reads a received answer frame (cmd, payload) to the request kind `to`. Returns CTRLBUS_OK;
 * CTRLBUS_ERR_FORMAT for a payload length (or value) the answer does not allow; CTRLBUS_ERR_UNSUPPORTED
 * for an unknown answer CMD, or an OK answer to a request that has no OK layout (SYNC, ECHO,
 * GET_AUXILIARY_ANCHOR); CTRLBUS_ERR_ARGUMENT for NULL pointers or a `to` that is not a request.
 * Empty OK answers (SET_BASE_MOTOR, POLL_BASE_ANS_CMD, SEND_EVENT, HEALTH_CLR_ERROR, BASE_CMD)
 * must have length 0. ISR-safe. Cost: O(len). */
int32_t ctrlbus_answer_decode(ctrlbus_answer_t *out, ctrlbus_req_kind_t to, uint8_t cmd,
                              const uint8_t *payload, size_t len);
#endif

/* The contract's name of an answer kind: "OK", "ERROR", "INVALID", "SYNC", "ECHO" (NULL when out of
 * range). ISR-safe. Cost: O(1). */
const char *ctrlbus_answer_name(ctrlbus_answer_kind_t kind);

/* Payload size of an answer, or CTRLBUS_ERR_ARGUMENT (inconsistent struct, or no OK layout).
 * ISR-safe. Cost: O(1). */
int32_t ctrlbus_answer_payload_size(const ctrlbus_answer_t *answer);

/* Writes a whole answer frame through sink. Returns the frame's size or a negative error as
 * ctrlbus_request_write(). ISR-safe if the sink's callback is. Cost: O(payload size). */
int32_t ctrlbus_answer_write(ctrlbus_sink_t *sink, const ctrlbus_answer_t *answer,
                             ctrlbus_frame_type_t type);

/* Encodes a whole answer frame into out[0..out_size). Returns its size or a negative error.
 * ISR-safe. Cost: O(payload size). */
int32_t ctrlbus_answer_encode(uint8_t *out, size_t out_size, const ctrlbus_answer_t *answer,
                              ctrlbus_frame_type_t type);

#ifdef __cplusplus
}
#endif

#endif
