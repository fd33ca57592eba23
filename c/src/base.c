/* SPDX-License-Identifier: MIT */
/* The base stack (see ctrlbus/base.h): receive ring, dispatch, answers, watchdog, limits. */
#include "ctrlbus/base.h"

#include <string.h>

#include "ctrlbus/diffdrive.h"

#include "codec.h"

/* base->flags */
#define FLAG_WATCHDOG_EXPIRED 0x01u /* the current silence has been acted on */
#define FLAG_MOTION_COMMANDED 0x02u /* the last motion command passed on was not zero */
#define FLAG_REBOOTED 0x04u         /* a reboot handler returned: drop the input, start afresh */

/* Time differences at or beyond this are taken as a clock that went backwards. */
#define TIME_BACKWARDS 0x80000000u
#define HEALTH_MESSAGE_MAX (CTRLBUS_HEALTH_MESSAGE_LEN - 1u)
#define HEALTH_LEVEL_BITS (CTRLBUS_HEALTH_WARNING | CTRLBUS_HEALTH_ERROR | CTRLBUS_HEALTH_FATAL)

/* What a base answers to each decoder event (docs/protocol.md §8.1); 0: nothing. */
static const uint16_t EVENT_ERRORS[] = {
    [CTRLBUS_RX_GARBAGE] = CTRLBUS_WIRE_ERR_NOT_SYNCHRONISED,
    [CTRLBUS_RX_CHECKSUM_ERROR] = CTRLBUS_WIRE_ERR_CHECKSUM,
    [CTRLBUS_RX_OVERSIZE] = CTRLBUS_WIRE_ERR_TOO_LONG,
    [CTRLBUS_RX_TIMEOUT] = 0,
    [CTRLBUS_RX_EMPTY_FRAME] = CTRLBUS_WIRE_ERR_FORMAT,
};

#if CTRLBUS_CONFIG_COMMAND_QUEUE
/* The external commands a Core knows (docs/protocol.md §5.12). */
static const uint8_t EXTERNAL_COMMANDS[] = {0x51, 0x52, 0x53, 0x80, 0x81, 0x82, 0x90,
                                            0xA0, 0xA1, 0xA2, 0xA3, 0xA4, 0xAF, 0xB0};
#endif

static void set_flags(ctrlbus_base_t *base, uint8_t flags)
{
    base->flags = (uint8_t)(base->flags | flags);
}

static void clear_flags(ctrlbus_base_t *base, uint8_t flags)
{
    base->flags = (uint8_t)(base->flags & (uint8_t)~flags);
}

/* ---- receive ring --------------------------------------------------------------------------- */

/* poll() hands the decoder a run of ring bytes shorter than this one byte at a time through
 * ctrlbus_decoder_push(), and a longer run through ctrlbus_decoder_take(), which checks a whole
 * frame in place: short runs are mostly frame pieces, which take() would copy anyway. */
#define PUSH_BELOW 16u

size_t ctrlbus_base_feed(ctrlbus_base_t *base, const uint8_t *data, size_t len)
{
    if (base == NULL || base->config == NULL || data == NULL) {
        return 0;
    }
    uint8_t *ring = base->config->rx_ring;
    uint16_t size = base->config->rx_ring_size;
    uint16_t head = base->rx_head; /* ours: only feed writes it */
    uint16_t tail = base->rx_tail; /* one snapshot: space freed later is used by the next feed */
    size_t taken = 0;
    while (taken < len) {
        uint16_t next = (uint16_t)(head + 1u == size ? 0u : head + 1u);
        if (next == tail) {
            base->rx_dropped += (uint32_t)(len - taken);
            break;
        }
        ring[head] = data[taken++];
        head = next;
    }
    CTRLBUS_RING_FENCE(); /* the bytes are in the ring before the index says so */
    base->rx_head = head;
    return taken;
}

/* ---- health registry ------------------------------------------------------------------------ */

#if CTRLBUS_CONFIG_HEALTH

/* With no storage the registry can only hold the watchdog's warning, which needs none. */
static uint32_t health_code_at(const ctrlbus_base_t *base, uint8_t index)
{
    const ctrlbus_base_health_entry_t *entries = base->config->health_entries;
    return entries != NULL ? entries[index].code : CTRLBUS_HEALTH_WATCHDOG_TRIPPED;
}

static const char *health_message_at(const ctrlbus_base_t *base, uint8_t index)
{
    const ctrlbus_base_health_entry_t *entries = base->config->health_entries;
    return entries != NULL ? entries[index].message : CTRLBUS_HEALTH_WATCHDOG_TRIPPED_MESSAGE;
}

static int32_t health_find(const ctrlbus_base_t *base, uint32_t code)
{
    for (uint8_t i = 0; i < base->health_count; i++) {
        if (health_code_at(base, i) == code) {
            return i;
        }
    }
    return -1;
}

int32_t ctrlbus_base_health_add(ctrlbus_base_t *base, uint32_t code, const char *message)
{
    if (base == NULL || base->config == NULL) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    /* The wire's rules for the message (docs/protocol.md §1.5): ASCII, room for the NUL. */
    for (size_t i = 0; message != NULL && message[i] != '\0'; i++) {
        if (i >= HEALTH_MESSAGE_MAX || (unsigned char)message[i] > 0x7Fu) {
            return CTRLBUS_ERR_ARGUMENT;
        }
    }
    if (health_find(base, code) >= 0) {
        return 0;
    }
    ctrlbus_base_health_entry_t *entries = base->config->health_entries;
    uint8_t capacity = entries != NULL ? base->config->health_capacity
                                       : (uint8_t)(code == CTRLBUS_HEALTH_WATCHDOG_TRIPPED);
    if (base->health_count >= capacity) {
        return CTRLBUS_ERR_TOO_BIG;
    }
    if (entries != NULL) {
        entries[base->health_count].code = code;
        entries[base->health_count].message = message;
    }
    base->health_count++;
    return 1;
}

int32_t ctrlbus_base_health_clear(ctrlbus_base_t *base, uint32_t code)
{
    if (base == NULL || base->config == NULL) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    int32_t found = health_find(base, code);
    if (found < 0) {
        return 0;
    }
    ctrlbus_base_health_entry_t *entries = base->config->health_entries;
    base->health_count--;
    for (uint8_t i = (uint8_t)found; entries != NULL && i < base->health_count; i++) {
        entries[i] = entries[i + 1u]; /* keep registration order */
    }
    return 1;
}

uint8_t ctrlbus_base_health_count(const ctrlbus_base_t *base)
{
    return base != NULL ? base->health_count : 0u;
}

#else /* the registry compiled out: see ctrlbus/ctrlbus_config.h */

int32_t ctrlbus_base_health_add(ctrlbus_base_t *base, uint32_t code, const char *message)
{
    (void)base;
    (void)code;
    (void)message;
    return CTRLBUS_ERR_UNSUPPORTED;
}

int32_t ctrlbus_base_health_clear(ctrlbus_base_t *base, uint32_t code)
{
    (void)base;
    (void)code;
    return CTRLBUS_ERR_UNSUPPORTED;
}

uint8_t ctrlbus_base_health_count(const ctrlbus_base_t *base)
{
    (void)base;
    return 0u;
}

#endif

/* ---- external-command queue ----------------------------------------------------------------- */

#if CTRLBUS_CONFIG_COMMAND_QUEUE

static uint8_t command_capacity(const ctrlbus_base_t *base)
{
    return base->config->command_queue != NULL ? base->config->command_queue_size : 1u;
}

static uint8_t command_at_head(const ctrlbus_base_t *base)
{
    const uint8_t *queue = base->config->command_queue;
    return queue != NULL ? queue[base->command_head] : base->command_head;
}

static void command_line(const ctrlbus_base_t *base, bool asserted)
{
    if (base->config->command_line != NULL) {
        base->config->command_line(base->config->context, asserted);
    }
}

int32_t ctrlbus_base_queue_command(ctrlbus_base_t *base, uint8_t code)
{
    if (base == NULL || base->config == NULL ||
        memchr(EXTERNAL_COMMANDS, code, sizeof EXTERNAL_COMMANDS) == NULL) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    uint8_t capacity = command_capacity(base);
    if (base->command_count >= capacity) {
        return CTRLBUS_ERR_TOO_BIG;
    }
    uint8_t *queue = base->config->command_queue;
    if (queue != NULL) {
        unsigned slot = (unsigned)base->command_head + base->command_count;
        queue[slot >= capacity ? slot - capacity : slot] = code;
    } else {
        base->command_head = code;
    }
    if (base->command_count++ == 0u) {
        command_line(base, true);
    }
    return CTRLBUS_OK;
}

/* POLL_BASE_ANS_CMD: the Core has taken the command at the head. */
static void command_taken(ctrlbus_base_t *base)
{
    if (base->command_count == 0u) {
        return;
    }
    if (base->config->command_queue != NULL) {
        unsigned next = base->command_head + 1u;
        base->command_head = (uint8_t)(next == command_capacity(base) ? 0u : next);
    }
    if (--base->command_count == 0u) {
        command_line(base, false);
    }
}

void ctrlbus_base_clear_commands(ctrlbus_base_t *base)
{
    if (base == NULL || base->config == NULL) {
        return;
    }
    bool was_pending = base->command_count != 0u;
    base->command_head = 0;
    base->command_count = 0;
    if (was_pending) {
        command_line(base, false);
    }
}

uint8_t ctrlbus_base_commands_pending(const ctrlbus_base_t *base)
{
    return base != NULL ? base->command_count : 0u;
}

#else /* no external commands: see ctrlbus/ctrlbus_config.h */

int32_t ctrlbus_base_queue_command(ctrlbus_base_t *base, uint8_t code)
{
    (void)base;
    (void)code;
    return CTRLBUS_ERR_UNSUPPORTED;
}

void ctrlbus_base_clear_commands(ctrlbus_base_t *base)
{
    (void)base;
}

uint8_t ctrlbus_base_commands_pending(const ctrlbus_base_t *base)
{
    (void)base;
    return 0u;
}

#endif

void ctrlbus_base_counters(const ctrlbus_base_t *base, ctrlbus_base_counters_t *out)
{
    if (out == NULL) {
        return;
    }
    out->watchdog_trips = base != NULL ? base->watchdog_trips : 0u;
    out->clamped_commands = base != NULL ? base->clamped_commands : 0u;
    out->rx_dropped = base != NULL ? base->rx_dropped : 0u;
}

/* ---- motion safety: watchdog and limits ----------------------------------------------------- */

static void stop_motors(const ctrlbus_base_t *base)
{
    const ctrlbus_base_config_t *config = base->config;
    if (config->stop_motors != NULL) {
        config->stop_motors(config->context);
    } else if (config->set_wheel_speeds != NULL) {
        (void)config->set_wheel_speeds(config->context, 0, 0);
    }
}

static void run_watchdog(ctrlbus_base_t *base, uint32_t now_ms)
{
    uint32_t period = base->config->watchdog_ms;
    if (period == 0u) {
        period = CTRLBUS_BASE_DEFAULT_WATCHDOG_MS;
    }
    uint32_t elapsed = now_ms - base->last_feed_ms;
    if (period == CTRLBUS_BASE_WATCHDOG_OFF || (base->flags & FLAG_WATCHDOG_EXPIRED) ||
        elapsed <= period || elapsed >= TIME_BACKWARDS) {
        return;
    }
    /* Once per silence; a stop of moving wheels is a trip the Core can read (§9.1). */
    bool moving = (base->flags & FLAG_MOTION_COMMANDED) != 0u;
    set_flags(base, FLAG_WATCHDOG_EXPIRED);
    clear_flags(base, FLAG_MOTION_COMMANDED);
    stop_motors(base);
    if (moving) {
        base->watchdog_trips++;
#if CTRLBUS_CONFIG_HEALTH
        (void)ctrlbus_base_health_add(base, CTRLBUS_HEALTH_WATCHDOG_TRIPPED,
                                      CTRLBUS_HEALTH_WATCHDOG_TRIPPED_MESSAGE);
#endif
    }
}

static void note_motion(ctrlbus_base_t *base, bool clamped, bool moving)
{
    if (clamped) {
        base->clamped_commands++;
    }
    if (moving) {
        set_flags(base, FLAG_MOTION_COMMANDED);
    } else {
        clear_flags(base, FLAG_MOTION_COMMANDED);
    }
}

#if CTRLBUS_CONFIG_LIMITS

/* floor(x * factor / divisor), for divisor in 1..2^31 and a result below 2^32: shift-and-subtract
 * long division of the 48-bit product, in 32-bit words. The limits are the only division in the
 * stack, and libgcc's 64-bit division would cost a Cortex-M0+ about 600 bytes. Cost: 32 steps. */
static uint32_t scale_magnitude(uint32_t x, uint16_t factor, uint32_t divisor)
{
    uint32_t middle = (x >> 16) * factor; /* the product is middle * 2^16 + low */
    uint32_t low = (x & 0xFFFFu) * factor;
    /* The product's low word is shifted out at the top while the quotient's bits come in at the
     * bottom; the remainder starts as the high word (bits 32..47), which is below divisor since
     * the quotient fits 32 bits. Below divisor <= 2^31 it can be doubled without overflow. */
    uint32_t quotient = low + (middle << 16);
    uint32_t remainder = (middle >> 16) + (quotient < low ? 1u : 0u);
    for (unsigned step = 0; step < 32u; step++) {
        remainder = (remainder << 1) | (quotient >> 31);
        quotient <<= 1;
        if (remainder >= divisor) {
            remainder -= divisor;
            quotient |= 1u;
        }
    }
    return quotient;
}

static uint32_t magnitude(int32_t value)
{
    return value < 0 ? 0u - (uint32_t)value : (uint32_t)value;
}

static int32_t with_sign_of(int32_t sign, uint32_t value)
{
    return sign < 0 ? -(int32_t)value : (int32_t)value; /* value <= 2^31 - 1 here */
}

/* Clamps *value to +-limit (0: no limit). Returns whether it changed. A limit above INT32_MAX
 * never acts: no magnitude exceeds it. */
static bool clamp_to(int32_t *value, uint32_t limit)
{
    if (limit == 0u || magnitude(*value) <= limit) {
        return false;
    }
    *value = with_sign_of(*value, limit);
    return true;
}

/* If the larger of |peak_a| and |peak_b| (wheel speeds, mm/s) exceeds limit (0: none), scales *a
 * and *b by limit / that peak, towards zero, so the path keeps its curvature (§9.2). Returns
 * whether it did. */
static bool scale_to(int32_t *a, int32_t *b, int32_t peak_a, int32_t peak_b, uint16_t limit)
{
    uint32_t peak = magnitude(peak_a) > magnitude(peak_b) ? magnitude(peak_a) : magnitude(peak_b);
    if (limit == 0u || peak <= limit) {
        return false;
    }
    /* limit / peak < 1, so each result is smaller than its input. One loop for a and b. */
    int32_t *value = a;
    for (unsigned i = 0; i < 2u; i++) {
        *value = with_sign_of(*value, scale_magnitude(magnitude(*value), limit, peak));
        value = b;
    }
    return true;
}

#endif /* CTRLBUS_CONFIG_LIMITS */

/* ---- answering ------------------------------------------------------------------------------ */

/* Keeps a helper with several callers out of line (GCC, clang): -Os alone copies it into each. */
#if defined(__GNUC__)
#define SHARED __attribute__((noinline))
#else
#define SHARED
#endif

static ctrlbus_frame_type_t answer_type(const ctrlbus_base_t *base)
{
    return base->config->standard_answers ? CTRLBUS_FRAME_AUTO : CTRLBUS_FRAME_LONG;
}

static uint16_t handler_error(int32_t result)
{
    return result == CTRLBUS_ERR_UNSUPPORTED ? CTRLBUS_WIRE_ERR_UNSUPPORTED
                                             : CTRLBUS_WIRE_ERR_OPERATION;
}

/* What a rebooted base forgets (docs/base-framework.md behaviour 12): the input not yet
 * answered, the command queue, the health list, the watchdog's state and the uptime origin. */
static void restart(ctrlbus_base_t *base, uint32_t now_ms)
{
    ctrlbus_base_clear_commands(base);
    base->health_count = 0;
    base->flags = FLAG_REBOOTED;
    base->last_feed_ms = now_ms;
    base->boot_ms = now_ms;
    ctrlbus_decoder_reset(&base->decoder);
}

/* The profile in force: a zero (reference) profile is the build's default. */
static ctrlbus_base_profile_t profile_of(const ctrlbus_base_config_t *config)
{
    return config->profile == CTRLBUS_PROFILE_REFERENCE ? CTRLBUS_DEFAULT_PROFILE : config->profile;
}

/* Whether the answers take the sdk2020 forms (a constant false without that profile). */
static bool sdk2020(const ctrlbus_base_config_t *config)
{
#if CTRLBUS_CONFIG_PROFILE_SDK2020
    return profile_of(config) == CTRLBUS_PROFILE_SDK2020;
#else
    (void)config;
    return false;
#endif
}

/* SET_BASE_MOTOR: the wheel limit, then the handler. Returns the handler's result. */
static int32_t set_wheel_speeds(ctrlbus_base_t *base, const ctrlbus_set_base_motor_request_t *motor)
{
    const ctrlbus_base_config_t *config = base->config;
    int32_t left = motor->speeds_mm_s[0];
    int32_t right = motor->speeds_mm_s[1];
    bool clamped = false;
#if CTRLBUS_CONFIG_LIMITS
    clamped = scale_to(&left, &right, left, right, config->limits.max_wheel_mm_s);
#endif
    note_motion(base, clamped, left != 0 || right != 0);
    return config->set_wheel_speeds(config->context, left, right);
}

/* SET_V_AND_GET_DEADRECKON: the limits, the handler, then the profile's timestamp. Returns the
 * handler's result. */
static int32_t set_velocity(ctrlbus_base_t *base, ctrlbus_set_v_and_get_deadreckon_request_t v,
                            ctrlbus_set_v_and_get_deadreckon_answer_t *out, uint32_t now_ms)
{
    const ctrlbus_base_config_t *config = base->config;
    bool clamped = false;
#if CTRLBUS_CONFIG_LIMITS
    const ctrlbus_base_limits_t *limits = &config->limits;
    clamped = clamp_to(&v.vx_mps_q16, limits->max_vx_mps_q16);
    clamped = clamp_to(&v.omega_radps_q16, limits->max_omega_radps_q16) || clamped;
    if (limits->wheel_track_mm != 0u) {
        int32_t left = 0;
        int32_t right = 0;
        ctrlbus_diffdrive_wheel_speeds(v.vx_mps_q16, v.omega_radps_q16, limits->wheel_track_mm,
                                       &left, &right);
        clamped =
            scale_to(&v.vx_mps_q16, &v.omega_radps_q16, left, right, limits->max_wheel_mm_s) ||
            clamped;
    }
#endif
    note_motion(base, clamped, v.vx_mps_q16 != 0 || v.vy_mps_q16 != 0 || v.omega_radps_q16 != 0);
    int32_t result = config->set_velocity(config->context, &v, out);
    if (!sdk2020(config)) {
        out->has_timestamp_ms = false;
    } else if (!out->has_timestamp_ms) {
        out->has_timestamp_ms = true;
        out->timestamp_ms = now_ms - base->boot_ms;
    }
    return result;
}

/* HEALTH_GET_HEALTH: the levels of the registered errors and their number. */
static void health_summary(const ctrlbus_base_t *base, ctrlbus_health_get_health_answer_t *out)
{
    out->flags = 0;
    out->error_count = 0;
#if CTRLBUS_CONFIG_HEALTH
    for (uint8_t i = 0; i < base->health_count; i++) {
        uint32_t level = health_code_at(base, i) >> 24;
        out->flags = (uint8_t)(out->flags | (level & HEALTH_LEVEL_BITS));
    }
    out->error_count = base->health_count;
#else
    (void)base;
#endif
}

/* HEALTH_GET_ERROR: the entry at index. Returns false when there is none. */
static bool health_entry(const ctrlbus_base_t *base, uint8_t index,
                         ctrlbus_health_get_error_answer_t *out)
{
#if CTRLBUS_CONFIG_HEALTH
    if (index >= base->health_count) {
        return false;
    }
    out->error_code = health_code_at(base, index);
    const char *message = health_message_at(base, index);
    for (size_t i = 0; message != NULL && message[i] != '\0' && i < HEALTH_MESSAGE_MAX; i++) {
        out->message[i] = message[i];
    }
    return true;
#else
    (void)base;
    (void)index;
    (void)out;
    return false;
#endif
}

/* POLL_BASE_CMD: the command at the head of the queue, in the profile's form. */
static void poll_answer(const ctrlbus_base_t *base, ctrlbus_poll_base_cmd_answer_t *out)
{
#if CTRLBUS_CONFIG_COMMAND_QUEUE
    out->has_command = base->command_count != 0u;
    out->command = out->has_command ? command_at_head(base) : 0u;
#endif
    /* Nothing pending: OK 0 (base_ref v4), or FF 00 for the SDK's fixed-size read. */
    out->payload_size =
        out->has_command || sdk2020(base->config) ? CTRLBUS_POLL_BASE_CMD_ANSWER_SIZE : 0u;
}

/* Where a handler's answer struct lives while the handler fills it and it is written. Only one
 * member is in use per request, and only that member is zeroed: this is storage, not a tagged
 * answer (nothing switches on it again). GET_BASE_CONF's answer, the largest layout, is not here:
 * it is written straight from the application's struct (config->base_conf). */
typedef union {
    ctrlbus_connect_base_answer_t connect_base;
    ctrlbus_get_base_status_answer_t get_base_status;
    ctrlbus_get_base_motor_data_answer_t get_base_motor_data;
    ctrlbus_get_base_sensor_data_answer_t get_base_sensor_data;
    ctrlbus_get_base_bumper_data_answer_t get_base_bumper_data;
    ctrlbus_get_charger_data_answer_t get_charger_data;
    ctrlbus_set_v_and_get_deadreckon_answer_t set_v_and_get_deadreckon;
    ctrlbus_poll_base_cmd_answer_t poll_base_cmd;
    ctrlbus_health_get_health_answer_t health_get_health;
    ctrlbus_health_get_error_answer_t health_get_error;
} answer_storage_t;

/* What a request is answered with when nothing failed: an OK frame of `size` payload bytes
 * (negative: a check refused the handler's struct), its layout (NULL: empty) and its struct. */
typedef struct {
    int32_t size;
    ctrlbus_codec_layout_t layout;
    const void *answer;
} reply_t;

/* answer_request's result besides 0 (the reply is to be written) and an ERROR code. */
#define ALREADY_ANSWERED 1u

/* The requests whose answer a handler (or the stack) fills into a struct: one switch; each case
 * zeroes and fills its own member of *out, computes its size once (the layout's _size, or the
 * constant) and names its layout. Returns 0 (reply set) or the ERROR code to answer with. */
static uint16_t answer_filled(ctrlbus_base_t *base, const ctrlbus_request_t *request,
                              answer_storage_t *out, reply_t *reply, uint32_t now_ms)
{
    const ctrlbus_base_config_t *config = base->config;
    void *context = config->context;
    int32_t result = CTRLBUS_ERR_UNSUPPORTED; /* the handler's; unsupported while it is missing */
    int32_t size = 0;
    ctrlbus_codec_layout_t layout = NULL;
    switch (request->kind) {
    case CTRLBUS_REQ_CONNECT_BASE:
        if (config->connect_info != NULL) {
            memset(&out->connect_base, 0, sizeof out->connect_base);
            result = config->connect_info(context, &out->connect_base);
            out->connect_base.has_firmware_version_suffix = sdk2020(config); /* the profile's size */
            size = ctrlbus_connect_base_answer_size(&out->connect_base);
            layout = ctrlbus_codec_connect_base_layout;
        }
        break;
    case CTRLBUS_REQ_GET_BASE_STATUS:
        if (config->status != NULL) {
            memset(&out->get_base_status, 0, sizeof out->get_base_status);
            result = config->status(context, &out->get_base_status);
            size = CTRLBUS_GET_BASE_STATUS_ANSWER_SIZE;
            layout = ctrlbus_codec_get_base_status_layout;
        }
        break;
    case CTRLBUS_REQ_GET_BASE_MOTOR_DATA:
        if (config->motor_data != NULL) {
            memset(&out->get_base_motor_data, 0, sizeof out->get_base_motor_data);
            result = config->motor_data(context, &out->get_base_motor_data);
            size = CTRLBUS_GET_BASE_MOTOR_DATA_ANSWER_SIZE;
            layout = ctrlbus_codec_get_base_motor_data_layout;
        }
        break;
    case CTRLBUS_REQ_GET_BASE_SENSOR_DATA:
        if (config->sensor_data != NULL) {
            memset(&out->get_base_sensor_data, 0, sizeof out->get_base_sensor_data);
            result = config->sensor_data(context, &out->get_base_sensor_data);
            size = CTRLBUS_GET_BASE_SENSOR_DATA_ANSWER_SIZE;
            layout = ctrlbus_codec_get_base_sensor_data_layout;
        }
        break;
    case CTRLBUS_REQ_GET_BASE_BUMPER_DATA:
        if (config->bumper_data != NULL) {
            memset(&out->get_base_bumper_data, 0, sizeof out->get_base_bumper_data);
            result = config->bumper_data(context, &out->get_base_bumper_data);
            if (out->get_base_bumper_data.payload_size == 0u || sdk2020(config)) {
                /* same value, padded */
                out->get_base_bumper_data.payload_size = CTRLBUS_GET_BASE_BUMPER_DATA_ANSWER_SIZE;
            }
            size = ctrlbus_get_base_bumper_data_answer_size(&out->get_base_bumper_data);
            layout = ctrlbus_codec_get_base_bumper_data_layout;
        }
        break;
    case CTRLBUS_REQ_GET_CHARGER_DATA:
        if (config->charger_data != NULL) {
            memset(&out->get_charger_data, 0, sizeof out->get_charger_data);
            result = config->charger_data(context, &out->get_charger_data);
            size = ctrlbus_get_charger_data_answer_size(&out->get_charger_data);
            layout = ctrlbus_codec_get_charger_data_layout;
        }
        break;
    case CTRLBUS_REQ_SET_V_AND_GET_DEADRECKON:
        if (config->set_velocity != NULL) {
            memset(&out->set_v_and_get_deadreckon, 0, sizeof out->set_v_and_get_deadreckon);
            result = set_velocity(base, request->as.set_v_and_get_deadreckon,
                                  &out->set_v_and_get_deadreckon, now_ms);
            size = ctrlbus_set_v_and_get_deadreckon_answer_size(&out->set_v_and_get_deadreckon);
            layout = ctrlbus_codec_set_v_and_get_deadreckon_layout;
        }
        break;
    case CTRLBUS_REQ_POLL_BASE_CMD:
        memset(&out->poll_base_cmd, 0, sizeof out->poll_base_cmd);
        poll_answer(base, &out->poll_base_cmd);
        result = CTRLBUS_OK;
        size = out->poll_base_cmd.payload_size; /* 0 or 2, consistent by construction */
        layout = ctrlbus_codec_poll_base_cmd_layout;
        break;
    case CTRLBUS_REQ_HEALTH_GET_HEALTH:
        health_summary(base, &out->health_get_health);
        result = CTRLBUS_OK;
        size = CTRLBUS_HEALTH_GET_HEALTH_ANSWER_SIZE;
        layout = ctrlbus_codec_health_get_health_layout;
        break;
    case CTRLBUS_REQ_HEALTH_GET_ERROR:
        memset(&out->health_get_error, 0, sizeof out->health_get_error);
        if (!health_entry(base, request->as.health_get_error.index, &out->health_get_error)) {
            return CTRLBUS_WIRE_ERR_OPERATION;
        }
        result = CTRLBUS_OK;
        size = ctrlbus_health_get_error_answer_size(&out->health_get_error);
        layout = ctrlbus_codec_health_get_error_layout;
        break;
    default: break; /* GET_AUXILIARY_ANCHOR has no layout, and features compiled out: 0x8000 */
    }
    if (result < 0) {
        return handler_error(result);
    }
    reply->size = size;
    reply->layout = layout;
    reply->answer = out;
    return 0;
}

/* Runs the application's part of a validated request: one dispatch per request. Returns 0 when
 * *reply is to be written, ALREADY_ANSWERED, or the ERROR code to answer with (nothing written
 * yet then). */
static uint16_t answer_request(ctrlbus_base_t *base, const ctrlbus_request_t *request,
                               answer_storage_t *out, reply_t *reply, ctrlbus_sink_t *sink,
                               ctrlbus_frame_type_t type, uint32_t now_ms)
{
    const ctrlbus_base_config_t *config = base->config;
    void *context = config->context;
    int32_t result = CTRLBUS_OK;
    switch (request->kind) {
    case CTRLBUS_REQ_GET_BASE_CONF:
        if (config->base_conf == NULL) {
            return CTRLBUS_WIRE_ERR_UNSUPPORTED;
        }
        /* Streamed from the application's struct: no copy on the stack. */
        reply->size = ctrlbus_get_base_conf_answer_size(config->base_conf);
        reply->layout = ctrlbus_codec_get_base_conf_layout;
        reply->answer = config->base_conf;
        return 0;
#if CTRLBUS_CONFIG_CONF_ADV
    case CTRLBUS_REQ_GET_BASE_CONF_ADV:
        if (config->binary_config == NULL || config->binary_config_size == 0u) {
            return CTRLBUS_WIRE_ERR_UNSUPPORTED;
        }
        /* The layout reads the blob pointer at the struct's start: binary_config itself. */
        reply->size = (int32_t)config->binary_config_size; /* init checked it */
        reply->layout = ctrlbus_codec_get_base_conf_adv_layout;
        reply->answer = &config->binary_config;
        return 0;
#endif
    case CTRLBUS_REQ_SET_BASE_MOTOR:
        result = config->set_wheel_speeds != NULL
                     ? set_wheel_speeds(base, &request->as.set_base_motor)
                     : CTRLBUS_ERR_UNSUPPORTED;
        break;
    case CTRLBUS_REQ_POLL_BASE_ANS_CMD:
#if CTRLBUS_CONFIG_COMMAND_QUEUE
        command_taken(base);
#endif
        break;
    case CTRLBUS_REQ_SEND_EVENT:
        if (config->on_event != NULL) {
            result = config->on_event(context, request->as.send_event.event);
        }
        break;
    case CTRLBUS_REQ_HEALTH_CLR_ERROR:
        if (ctrlbus_base_health_clear(base, request->as.health_clr_error.error_code) <= 0) {
            return CTRLBUS_WIRE_ERR_OPERATION; /* not registered (or no registry) */
        }
        break;
    case CTRLBUS_REQ_BASE_CMD: {
        /* Its hook runs once the answer is out. */
        bool reboot = request->as.base_cmd.subcommand == CTRLBUS_BASE_CMD_REBOOT;
        void (*hook)(void *) = reboot ? config->reboot : config->enter_dfu;
        if (hook == NULL) {
            return CTRLBUS_WIRE_ERR_UNSUPPORTED;
        }
        (void)ctrlbus_codec_write_ok(sink, 0, NULL, NULL, type);
        if (reboot) {
            restart(base, now_ms); /* what a handler that returns (a host base) finds */
        }
        hook(context);
        return ALREADY_ANSWERED;
    }
    default: return answer_filled(base, request, out, reply, now_ms);
    }
    return result < 0 ? handler_error(result) : 0u; /* the empty OKs: reply as set */
}

/* Decodes a request, runs it and writes its one answer (OK, ERROR, or the SYNC/ECHO copy), or
 * writes the ERROR for a decoder event (rx not CTRLBUS_RX_FRAME): the one place answers leave. */
static void answer(ctrlbus_base_t *base, ctrlbus_rx_t rx, const ctrlbus_frame_t *frame,
                   uint32_t now_ms, ctrlbus_sink_t *sink, ctrlbus_frame_type_t type)
{
    uint16_t error;
    ctrlbus_request_t request;
    answer_storage_t out;
    reply_t reply = {0, NULL, NULL};
    if (rx != CTRLBUS_RX_FRAME) {
        error = (size_t)rx < sizeof EVENT_ERRORS / sizeof EVENT_ERRORS[0] ? EVENT_ERRORS[rx] : 0u;
        if (error == CTRLBUS_WIRE_ERR_CHECKSUM && base->config->reference_checksum_code) {
            error = CTRLBUS_WIRE_ERR_CHECKSUM_REFERENCE;
        }
        if (error == 0u) {
            return; /* a timeout: nothing to say */
        }
    } else if (frame->cmd == CTRLBUS_CMD_SYNC || frame->cmd == CTRLBUS_CMD_ECHO) {
        /* The request copied verbatim, flag and checksum included; not motor traffic. */
        (void)ctrlbus_frame_write(sink, frame->cmd, frame->payload, frame->payload_len,
                                  frame->is_long ? CTRLBUS_FRAME_LONG : CTRLBUS_FRAME_STANDARD);
        return;
    } else {
        if (frame->cmd == CTRLBUS_CMD_CTRL_BUS) {
            /* Any CTRL_BUS frame that passed its checksum shows that the Core is alive (§9.1). */
            base->last_feed_ms = now_ms;
            clear_flags(base, FLAG_WATCHDOG_EXPIRED);
        }
        int32_t result =
            ctrlbus_request_decode(&request, frame->cmd, frame->payload, frame->payload_len);
        error = result < 0 ? ctrlbus_request_error_code(&request, result)
                           : answer_request(base, &request, &out, &reply, sink, type, now_ms);
        if (error == ALREADY_ANSWERED) {
            return;
        }
        /* A struct the check refuses (text that is not ASCII, a count over 8, ...) is a handler
         * failure; it is found before any byte goes out. */
        if (error == 0u && reply.size < 0) {
            error = CTRLBUS_WIRE_ERR_OPERATION;
        }
    }
    /* A write callback's failure cuts an answer short; there is nothing more to say. */
    if (error != 0u) {
        (void)ctrlbus_error_answer_write(sink, error, type);
    } else {
        (void)ctrlbus_codec_write_ok(sink, reply.size, reply.layout, reply.answer, type);
    }
}

/* Answers `first` (a result ctrlbus_decoder_push() returned, with *first_frame; NONE or BUSY for
 * none), then every result the decoder has ready. Returns how many there were. */
static unsigned drain(ctrlbus_base_t *base, uint32_t now_ms, ctrlbus_rx_t first,
                      const ctrlbus_frame_t *first_frame)
{
    const ctrlbus_base_config_t *config = base->config;
    ctrlbus_sink_t sink;
    (void)ctrlbus_sink_init(&sink, config->write, config->write_context);
    unsigned results = 0;
    ctrlbus_frame_t frame;
    ctrlbus_frame_type_t type = answer_type(base);
    if (first != CTRLBUS_RX_NONE && first != CTRLBUS_RX_BUSY) {
        frame = *first_frame;
    } else {
        first = ctrlbus_decoder_next(&base->decoder, &frame);
    }
    for (ctrlbus_rx_t rx = first; rx != CTRLBUS_RX_NONE;
         rx = ctrlbus_decoder_next(&base->decoder, &frame)) {
        results++;
        answer(base, rx, &frame, now_ms, &sink, type);
    }
    return results;
}

/* After a reboot handler returned: what was received before the reset is not heard. */
static bool dropped_after_reboot(ctrlbus_base_t *base)
{
    if (!(base->flags & FLAG_REBOOTED)) {
        return false;
    }
    clear_flags(base, FLAG_REBOOTED);
    uint16_t head = base->rx_head;
    CTRLBUS_RING_FENCE();
    base->rx_tail = head;
    return true;
}

void ctrlbus_base_poll(ctrlbus_base_t *base, uint32_t now_ms)
{
    if (base == NULL || base->config == NULL) {
        return;
    }
    const ctrlbus_base_config_t *config = base->config;
    run_watchdog(base, now_ms);
    /* Only what is in the ring now: an interrupt that keeps feeding cannot keep us here. */
    uint16_t head = base->rx_head;
    CTRLBUS_RING_FENCE(); /* the bytes up to head are read only after head is */
    uint16_t tail = base->rx_tail;
    while (tail != head) {
        uint16_t end = head > tail ? head : config->rx_ring_size;
        const uint8_t *bytes = config->rx_ring + tail;
        size_t run = (size_t)(end - tail);
        size_t used = 0;
        ctrlbus_rx_t rx = CTRLBUS_RX_NONE;
        ctrlbus_frame_t frame;
        if (run < PUSH_BELOW) {
            /* A few bytes: one push each (its inline path), until one completes a result. */
            while (used < run &&
                   (rx = ctrlbus_decoder_push(&base->decoder, bytes[used], now_ms, &frame)) ==
                       CTRLBUS_RX_NONE) {
                used++;
            }
            if (rx != CTRLBUS_RX_NONE && rx != CTRLBUS_RX_BUSY) {
                used++; /* the byte that completed the result was taken too */
            }
        } else {
            /* More: take() up to the first result; a whole frame in the run is handed out in
             * place, its payload still in the ring. */
            const uint8_t *at = bytes;
            size_t left = run;
            rx = ctrlbus_decoder_take(&base->decoder, &at, &left, now_ms, &frame);
            used = run - left;
        }
        /* NONE from push or take means nothing waits. The result is answered before its bytes'
         * slots are released, since a frame taken in place still lies in them. */
        unsigned results = rx == CTRLBUS_RX_NONE ? 0u : drain(base, now_ms, rx, &frame);
        tail = (uint16_t)(tail + used);
        if (tail == config->rx_ring_size) {
            tail = 0;
        }
        CTRLBUS_RING_FENCE(); /* done with those bytes before feed may reuse their slots */
        base->rx_tail = tail;
        if (dropped_after_reboot(base)) {
            return;
        }
        if (used == 0u && results == 0u) {
            break; /* cannot happen with a valid decoder; never spin */
        }
    }
    ctrlbus_decoder_tick(&base->decoder, now_ms);
    (void)drain(base, now_ms, CTRLBUS_RX_NONE, NULL);
    (void)dropped_after_reboot(base);
}

/* Whether config asks for a feature that this build compiled out (ctrlbus/ctrlbus_config.h). */
static bool needs_missing_feature(const ctrlbus_base_config_t *config)
{
    bool missing = false;
#if !CTRLBUS_CONFIG_HEALTH
    missing = missing || config->health_entries != NULL;
#endif
#if !CTRLBUS_CONFIG_COMMAND_QUEUE
    missing = missing || config->command_queue != NULL;
#endif
#if !CTRLBUS_CONFIG_LIMITS
    const ctrlbus_base_limits_t *limits = &config->limits;
    missing = missing || limits->max_wheel_mm_s != 0u || limits->wheel_track_mm != 0u ||
              limits->max_vx_mps_q16 != 0u || limits->max_omega_radps_q16 != 0u;
#endif
#if !CTRLBUS_CONFIG_PROFILE_SDK2020
    missing = missing || config->profile == CTRLBUS_PROFILE_SDK2020;
#endif
#if !CTRLBUS_CONFIG_CONF_ADV
    missing = missing || config->binary_config != NULL;
#endif
    (void)config;
    return missing;
}

int32_t ctrlbus_base_init(ctrlbus_base_t *base, const ctrlbus_base_config_t *config,
                          uint32_t now_ms)
{
    if (base == NULL || config == NULL || config->write == NULL || config->rx_ring == NULL ||
        config->rx_ring_size < 2u || config->binary_config_size > CTRLBUS_LONG_PAYLOAD_MAX ||
        (config->profile != CTRLBUS_PROFILE_REFERENCE &&
         config->profile != CTRLBUS_PROFILE_SDK2020) ||
        (profile_of(config) == CTRLBUS_PROFILE_SDK2020 && config->standard_answers)) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    if (needs_missing_feature(config)) {
        return CTRLBUS_ERR_UNSUPPORTED;
    }
    uint16_t timeout = config->frame_timeout_ms;
    if (timeout == 0u) {
        timeout = CTRLBUS_DEFAULT_TIMEOUT_MS;
    } else if (timeout == CTRLBUS_BASE_TIMEOUT_OFF) {
        timeout = 0;
    }
    /* Checks frame_buffer and its size. */
    int32_t result = ctrlbus_decoder_init(&base->decoder, config->frame_buffer,
                                          config->frame_buffer_size, timeout,
                                          config->decoder_stats);
    if (result < 0) {
        return result;
    }
    base->config = config;
    base->rx_head = 0;
    base->rx_tail = 0;
    base->rx_dropped = 0;
    base->last_feed_ms = now_ms;
    base->boot_ms = now_ms;
    base->watchdog_trips = 0;
    base->clamped_commands = 0;
    base->health_count = 0;
    base->command_head = 0;
    base->command_count = 0;
    base->flags = 0;
    return CTRLBUS_OK;
}

void ctrlbus_base_reset_line(ctrlbus_base_t *base)
{
    if (base == NULL || base->config == NULL) {
        return;
    }
    uint16_t head = base->rx_head;
    CTRLBUS_RING_FENCE();
    base->rx_tail = head;
    ctrlbus_decoder_reset(&base->decoder);
}
