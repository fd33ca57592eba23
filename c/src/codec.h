/* SPDX-License-Identifier: MIT */
/* Private to the library: the field readers and protocol facts that both halves of the message
 * codecs use (messages.c, what a base sends and reads; messages_master.c, what a master sends
 * and reads), and the answer writers the base stack shares with messages.c. Not installed, not
 * part of the API. */
#ifndef CTRLBUS_SRC_CODEC_H
#define CTRLBUS_SRC_CODEC_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ctrlbus/messages.h"

/* The codec's constant tables live in flash. Every other target reads flash with ordinary loads;
 * an AVR keeps plain `const` data in its scarce RAM, so there they are PROGMEM and each byte is
 * read with pgm_read_byte. Read table bytes only through CODEC_ROM_BYTE. */
#if defined(__AVR__)
#include <avr/pgmspace.h>
#define CODEC_ROM PROGMEM
#define CODEC_ROM_BYTE(address) pgm_read_byte(address)
#else
#define CODEC_ROM
#define CODEC_ROM_BYTE(address) (*(address))
#endif

/* ---- reading fields: callers check the payload length first ---------------------------------- */

static inline uint8_t codec_take_u8(const uint8_t **p)
{
    uint8_t value = (*p)[0];
    *p += 1;
    return value;
}

static inline uint16_t codec_take_u16(const uint8_t **p)
{
    uint16_t value = (uint16_t)((uint16_t)(*p)[0] | (uint16_t)((uint16_t)(*p)[1] << 8));
    *p += 2;
    return value;
}

/* A little-endian 32-bit word at b (any alignment). */
static inline uint32_t codec_read_u32(const uint8_t *b)
{
    return (uint32_t)b[0] | ((uint32_t)b[1] << 8) | ((uint32_t)b[2] << 16) |
           ((uint32_t)b[3] << 24);
}

/* The same as a signed word: two's complement without relying on implementation-defined
 * conversions. No pointer to a pointer: the base stack's callers keep nothing on the stack. */
static inline int32_t codec_read_s32(const uint8_t *b)
{
    uint32_t value = codec_read_u32(b);
    if (value <= 0x7FFFFFFFu) {
        return (int32_t)value;
    }
    return (int32_t)(value - 0x80000000u) - INT32_MAX - 1;
}

static inline uint32_t codec_take_u32(const uint8_t **p)
{
    uint32_t value = codec_read_u32(*p);
    *p += 4;
    return value;
}

static inline int32_t codec_take_s32(const uint8_t **p)
{
    int32_t value = codec_read_s32(*p);
    *p += 4;
    return value;
}

/* ---- argument values the protocol defines (others: well-formed but unsupported, 0x8000) ---- */

static inline bool codec_base_cmd_known(uint8_t subcommand)
{
    return subcommand == CTRLBUS_BASE_CMD_ENTER_DFU || subcommand == CTRLBUS_BASE_CMD_REBOOT;
}

static inline bool codec_connect_version_known(uint8_t version)
{
    return version == CTRLBUS_PROTOCOL_VERSION;
}

static inline bool codec_charger_type_known(uint8_t data_type)
{
    return data_type == CTRLBUS_CHARGER_DATA_BEACONS;
}

/* Requests whose OK answer has an empty payload. */
static inline bool codec_has_empty_ok(ctrlbus_req_kind_t kind)
{
    return kind == CTRLBUS_REQ_SET_BASE_MOTOR || kind == CTRLBUS_REQ_POLL_BASE_ANS_CMD ||
           kind == CTRLBUS_REQ_SEND_EVENT || kind == CTRLBUS_REQ_HEALTH_CLR_ERROR ||
           kind == CTRLBUS_REQ_BASE_CMD;
}

/* ---- the control-bus requests: how each travels in a CMD 0xF8 payload (messages.c) ---------- */

typedef struct {
    uint8_t kind; /* ctrlbus_req_kind_t */
    uint8_t code;
    uint8_t subcommand; /* HEALTH_MGMT only */
    uint8_t size;       /* whole payload, code (and sub-command) included */
} ctrlbus_codec_request_layout_t;

#define CTRLBUS_CODEC_REQUEST_LAYOUTS 17u
extern const ctrlbus_codec_request_layout_t ctrlbus_codec_request_layouts[CTRLBUS_CODEC_REQUEST_LAYOUTS]
    CODEC_ROM;

/* ---- the sink's unchecked core (frame.c) ------------------------------------------------------ */

/* What the public ctrlbus_sink_begin/_put/_end do once their arguments are checked; the base stack
 * calls them directly, since its answers are right by construction. */

/* Starts a frame of payload_len bytes (at most 65534, and 254 unless is_long): writes its header. */
void ctrlbus_sink_start(ctrlbus_sink_t *sink, uint8_t cmd, size_t payload_len, bool is_long);

/* Payload bytes, counted off the announced length (more than announced fails the frame with
 * CTRLBUS_ERR_LENGTH and writes nothing). data must not be NULL when len > 0. */
void ctrlbus_sink_emit(ctrlbus_sink_t *sink, const uint8_t *data, size_t len);

/* Writes the checksum unless an error came first (fewer bytes than announced: LENGTH). Returns
 * the frame's status: CTRLBUS_OK or its first error. */
int32_t ctrlbus_sink_finish(ctrlbus_sink_t *sink);

/* ---- writing answers: what messages.c shares with the base stack --------------------------- */

/* An answer layout: its fields in wire order, each read from the answer struct at `offset`:
 * a table walked by one writer (ctrlbus_codec_put_fields) instead of one function per layout.
 * Two bytes a field and no end mark: the size the answer's check gave ends the walk (it never
 * exceeds what the fields hold; a shorter size drops the optional tail fields, or cuts the
 * bumper word short). A field's shape byte is its count << 2 | its kind; count 0 is the BYTES
 * field, always last. */
typedef enum {
    FIELD_U8 = 0,  /* `count` uint8_t (or bool) values */
    FIELD_U16 = 1, /* `count` uint16_t values, little-endian */
    FIELD_U32 = 2, /* `count` uint32_t or int32_t values, little-endian (two's complement) */
    FIELD_TEXT = 3 /* a char array: its text up to the NUL, zero-padded to `count` bytes */
} ctrlbus_codec_field_kind_t; /* an integer kind is log2 of its width */

typedef struct {
    uint8_t offset; /* offsetof the member in the layout's struct */
    uint8_t shape;  /* count << 2 | kind (ctrlbus_codec_field_kind_t); 0: a BYTES field */
} ctrlbus_codec_field_t;

/* `count` (1..63) values of `kind` in `member` of `type`. */
#define CODEC_FIELD(type, member, kind, count) \
    {(uint8_t)offsetof(type, member), (uint8_t)((count) << 2 | (kind))}
/* A `const uint8_t *` member: the rest of the payload, whatever its length. */
#define CODEC_FIELD_BYTES(type, member) {(uint8_t)offsetof(type, member), 0u}

typedef const ctrlbus_codec_field_t *ctrlbus_codec_layout_t;

/* Writes `size` payload bytes of an answer struct through its layout (NULL: the struct's first
 * `size` bytes as they are, a byte array); the struct has been checked (its _size gave `size`),
 * and the size ends the walk (optional tail fields, the short bumper form). */
void ctrlbus_codec_put_fields(ctrlbus_sink_t *sink, ctrlbus_codec_layout_t layout,
                              const void *answer, size_t size);

/* An OK answer frame of `size` payload bytes (a negative size is a check's error, returned
 * before anything is written), its payload as ctrlbus_codec_put_fields() writes it, its checksum.
 * Returns the frame's size or a negative error. */
int32_t ctrlbus_codec_write_ok(ctrlbus_sink_t *sink, int32_t size, ctrlbus_codec_layout_t layout,
                               const void *answer, ctrlbus_frame_type_t type);

/* Each answer's layout (messages.c). */
/* BEGIN GENERATED layout declarations (make generate: from protocol/ctrlbus.json) */
extern const ctrlbus_codec_field_t ctrlbus_codec_connect_base_layout[] CODEC_ROM;
extern const ctrlbus_codec_field_t ctrlbus_codec_get_base_conf_layout[] CODEC_ROM;
extern const ctrlbus_codec_field_t ctrlbus_codec_get_base_conf_adv_layout[] CODEC_ROM;
extern const ctrlbus_codec_field_t ctrlbus_codec_get_base_status_layout[] CODEC_ROM;
extern const ctrlbus_codec_field_t ctrlbus_codec_get_base_motor_data_layout[] CODEC_ROM;
extern const ctrlbus_codec_field_t ctrlbus_codec_get_base_sensor_data_layout[] CODEC_ROM;
extern const ctrlbus_codec_field_t ctrlbus_codec_get_base_bumper_data_layout[] CODEC_ROM;
extern const ctrlbus_codec_field_t ctrlbus_codec_get_charger_data_layout[] CODEC_ROM;
extern const ctrlbus_codec_field_t ctrlbus_codec_set_v_and_get_deadreckon_layout[] CODEC_ROM;
extern const ctrlbus_codec_field_t ctrlbus_codec_health_get_health_layout[] CODEC_ROM;
extern const ctrlbus_codec_field_t ctrlbus_codec_health_get_error_layout[] CODEC_ROM;
/* END GENERATED layout declarations */

#endif
