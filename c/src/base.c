/* SPDX-License-Identifier: MIT */
/* The base stack (see ctrlbus/base.h): receive ring, dispatch, answers, watchdog, limits. */
#include "ctrlbus/base.h"

#include <string.h>

#include "ctrlbus/diffdrive.h"

#include "codec.h"

/* CTRLBUS_CONST_IN_FLASH: base_conf and binary_config are read through CTRLBUS_READ_CONST
 * (ctrlbus_config.h), in wire order straight from memory, as the codec does on a little-endian
 * CPU. */
#if CTRLBUS_CONST_IN_FLASH
#if !defined(CTRLBUS_READ_CONST) && defined(__AVR__)
#define CTRLBUS_READ_CONST(dst, src, size) memcpy_P((dst), (src), (size))
#define READ_CONST_BYTE(address) pgm_read_byte(address) /* the same, inline */
#endif
#ifndef CTRLBUS_READ_CONST
#define CTRLBUS_READ_CONST(dst, src, size) memcpy((dst), (src), (size))
#endif
#ifndef READ_CONST_BYTE
static uint8_t read_const_byte(const uint8_t *address)
{
    uint8_t byte;
    CTRLBUS_READ_CONST(&byte, address, 1u);
    return byte;
}
#define READ_CONST_BYTE(address) read_const_byte(address)
#endif
#if !(defined(__BYTE_ORDER__) && defined(__ORDER_LITTLE_ENDIAN__) &&                              \
      __BYTE_ORDER__ == __ORDER_LITTLE_ENDIAN__)
#error "CTRLBUS_CONST_IN_FLASH needs a little-endian CPU"
#endif
#endif

/* Keeps a function out of line (GCC, clang): its frame is then on the stack only
 * while it runs (answer(): not while the decoder works), or its code is there once. */
#if defined(__GNUC__)
#define NOINLINE __attribute__((noinline))
#else
#define NOINLINE
#endif

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

bool ctrlbus_base_feed_byte(ctrlbus_base_t *base, uint8_t byte)
{
    if (base == NULL || base->config == NULL) {
        return false;
    }
    const ctrlbus_base_config_t *config = base->config;
    uint16_t head = base->rx_head;
    uint16_t next = (uint16_t)(head + 1u == config->rx_ring_size ? 0u : head + 1u);
    if (next == base->rx_tail) {
        base->rx_dropped += 1u;
        return false;
    }
    config->rx_ring[head] = byte;
    CTRLBUS_RING_FENCE(); /* the byte is in the ring before the index says so */
    base->rx_head = next;
    return true;
}

size_t ctrlbus_base_rx_free(const ctrlbus_base_t *base)
{
    if (base == NULL || base->config == NULL) {
        return 0u;
    }
    /* One slot stays empty, so that a full ring is told from an empty one (head == tail). */
    uint16_t head = base->rx_head, tail = base->rx_tail, size = base->config->rx_ring_size;
    uint16_t used = (uint16_t)(head >= tail ? head - tail : size - tail + head);
    return (size_t)(size - 1u - used);
}

size_t ctrlbus_base_feed(ctrlbus_base_t *base, const uint8_t *data, size_t len)
{
    size_t taken = 0;
    if (data != NULL) {
        /* Byte by byte: each is published as soon as it is in (a caller that can wait, such as a
         * host thread, may offer the rest again later). */
        while (taken < len && ctrlbus_base_feed_byte(base, data[taken])) {
            taken++;
        }
        if (taken < len && base != NULL && base->config != NULL) {
            base->rx_dropped += (uint32_t)(len - taken - 1u); /* feed_byte counted the first */
        }
    }
    return taken;
}

/* ---- health registry ------------------------------------------------------------------------ */

#if CTRLBUS_CONFIG_HEALTH

/* With no storage the registry can only hold the watchdog's warning, which needs none. (No
 * constant entry stands for it: an AVR would keep that in RAM.) */
static uint32_t health_code_at(const ctrlbus_base_health_entry_t *entries, uint8_t index)
{
    return entries != NULL ? entries[index].code : CTRLBUS_HEALTH_WATCHDOG_TRIPPED;
}

static const char *health_message_at(const ctrlbus_base_health_entry_t *entries, uint8_t index)
{
    return entries != NULL ? entries[index].message : CTRLBUS_HEALTH_WATCHDOG_TRIPPED_MESSAGE;
}

static NOINLINE int32_t health_find(const ctrlbus_base_t *base, uint32_t code)
{
    const ctrlbus_base_health_entry_t *entries = base->config->health_entries;
    for (uint8_t i = 0; i < base->health_count; i++) {
        if (health_code_at(entries, i) == code) {
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
    /* CTRLBUS_BASE_WATCHDOG_OFF is the largest period: no elapsed time exceeds it. */
    if ((base->flags & FLAG_WATCHDOG_EXPIRED) || elapsed <= period || elapsed >= TIME_BACKWARDS) {
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

static NOINLINE void note_motion(ctrlbus_base_t *base, bool clamped, bool moving)
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
static NOINLINE bool clamp_to(int32_t *value, uint32_t limit)
{
    if (limit == 0u || magnitude(*value) <= limit) {
        return false;
    }
    *value = with_sign_of(*value, limit);
    return true;
}

/* If the larger of |peaks[0]| and |peaks[1]| (wheel speeds, mm/s) exceeds limit (0: none),
 * scales *a and *b by limit / that peak, towards zero, so the path keeps its curvature (§9.2);
 * peaks may be a and b themselves. Returns whether it did. */
static bool scale_to(int32_t *a, int32_t *b, const int32_t peaks[2], uint16_t limit)
{
    uint32_t peak_a = magnitude(peaks[0]);
    uint32_t peak_b = magnitude(peaks[1]);
    uint32_t peak = peak_a > peak_b ? peak_a : peak_b;
    if (limit == 0u || peak <= limit) {
        return false;
    }
    /* limit / peak < 1, so each result is smaller than its input. One loop for a, then b. */
    int32_t *value = a;
    for (;;) {
        *value = with_sign_of(*value, scale_magnitude(magnitude(*value), limit, peak));
        if (value == b) {
            return true;
        }
        value = b;
    }
}

#endif /* CTRLBUS_CONFIG_LIMITS */

/* ---- answering ------------------------------------------------------------------------------ */

/* What a rebooted base forgets (docs/base-framework.md behaviour 12): the input not yet
 * answered, the command queue, the health list, the watchdog's state and the uptime origin. */
static void restart(ctrlbus_base_t *base, uint32_t now_ms)
{
    ctrlbus_base_clear_commands(base);
    base->health_count = 0;
    base->flags = FLAG_REBOOTED;
    base->last_feed_ms = now_ms;
    base->boot_ms = now_ms;
    ctrlbus_base_reset_line(base); /* the ring's bytes and the decoder's: poll takes no more */
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

/* SET_BASE_MOTOR (its arguments: four wheel speeds, the last two ignored): the wheel limit, then
 * the handler, the speeds worked on in wheels (the answer storage: nothing on the stack).
 * Returns the handler's result. */
static int32_t set_wheel_speeds(ctrlbus_base_t *base, const uint8_t *args, int32_t wheels[2])
{
    const ctrlbus_base_config_t *config = base->config;
    wheels[0] = codec_read_s32(args);
    wheels[1] = codec_read_s32(args + 4);
    bool clamped = false;
#if CTRLBUS_CONFIG_LIMITS
    clamped = scale_to(&wheels[0], &wheels[1], wheels, config->limits.max_wheel_mm_s);
#endif
    note_motion(base, clamped, (wheels[0] | wheels[1]) != 0);
    return config->set_wheel_speeds(config->context, wheels[0], wheels[1]);
}

/* SET_V_AND_GET_DEADRECKON's part of the answer storage: the handler's input and its answer. */
typedef struct {
    ctrlbus_set_v_and_get_deadreckon_answer_t answer;
    ctrlbus_set_v_and_get_deadreckon_request_t velocity;
    int32_t wheels[2]; /* the limits' wheel speeds: here, not on the stack (poll's deepest path) */
} motion_storage_t;

/* SET_V_AND_GET_DEADRECKON (its arguments: vx, vy, omega): the limits, the handler, then the
 * profile's timestamp. Returns the handler's result. */
static int32_t set_velocity(ctrlbus_base_t *base, const uint8_t *args, motion_storage_t *motion,
                            uint32_t now_ms)
{
    const ctrlbus_base_config_t *config = base->config;
    ctrlbus_set_v_and_get_deadreckon_request_t *v = &motion->velocity;
    ctrlbus_set_v_and_get_deadreckon_answer_t *out = &motion->answer;
    v->vx_mps_q16 = codec_read_s32(args);
    v->vy_mps_q16 = codec_read_s32(args + 4);
    v->omega_radps_q16 = codec_read_s32(args + 8);
    bool clamped = false;
#if CTRLBUS_CONFIG_LIMITS
    const ctrlbus_base_limits_t *limits = &config->limits;
    clamped = clamp_to(&v->vx_mps_q16, limits->max_vx_mps_q16);
    clamped |= clamp_to(&v->omega_radps_q16, limits->max_omega_radps_q16);
    if (limits->wheel_track_mm != 0u) {
        int32_t *wheels = motion->wheels;
        ctrlbus_diffdrive_wheel_speeds(v->vx_mps_q16, v->omega_radps_q16, limits->wheel_track_mm,
                                       &wheels[0], &wheels[1]);
        clamped |= scale_to(&v->vx_mps_q16, &v->omega_radps_q16, wheels, limits->max_wheel_mm_s);
    }
#endif
    note_motion(base, clamped,
                (v->vx_mps_q16 | v->vy_mps_q16 | v->omega_radps_q16) != 0);
    int32_t result = config->set_velocity(config->context, v, out);
    if (!sdk2020(config)) {
        out->has_timestamp_ms = false;
    } else if (!out->has_timestamp_ms) {
        out->has_timestamp_ms = true;
        out->timestamp_ms = now_ms - base->boot_ms;
    }
    return result;
}

/* HEALTH_GET_HEALTH's two bytes: the levels of the registered errors and their number. */
static void health_summary(const ctrlbus_base_t *base, uint8_t out[2])
{
    uint8_t flags = 0;
#if CTRLBUS_CONFIG_HEALTH
    const ctrlbus_base_health_entry_t *entries = base->config->health_entries;
    for (uint8_t i = 0; i < base->health_count; i++) {
        flags = (uint8_t)(flags | ((health_code_at(entries, i) >> 24) & HEALTH_LEVEL_BITS));
    }
    out[1] = base->health_count;
#else
    (void)base;
    out[1] = 0;
#endif
    out[0] = flags;
}

/* HEALTH_GET_ERROR: the entry at index (out zeroed). Returns false when there is none. */
static bool health_entry(const ctrlbus_base_t *base, uint8_t index,
                         ctrlbus_health_get_error_answer_t *out)
{
#if CTRLBUS_CONFIG_HEALTH
    if (index >= base->health_count) {
        return false;
    }
    const ctrlbus_base_health_entry_t *entries = base->config->health_entries;
    out->error_code = health_code_at(entries, index);
    const char *message = health_message_at(entries, index);
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

/* Where the answer to the request being handled lives while a handler fills it and it is
 * written: on poll's stack, as large as the largest member (GET_BASE_SENSOR_DATA's 64 bytes).
 * All of it is zeroed before a request runs: one constant-size memset is less code than a
 * size per request. GET_BASE_CONF and the 0x21 blob are written from the application's own
 * storage instead. */
typedef union {
    ctrlbus_connect_base_answer_t connect_base;
    ctrlbus_get_base_status_answer_t get_base_status;
    ctrlbus_get_base_motor_data_answer_t get_base_motor_data;
    ctrlbus_get_base_sensor_data_answer_t get_base_sensor_data;
    ctrlbus_get_base_bumper_data_answer_t get_base_bumper_data;
    ctrlbus_get_charger_data_answer_t get_charger_data;
    motion_storage_t motion;
    ctrlbus_health_get_error_answer_t health_get_error;
    uint8_t bytes[2]; /* written as they are: an ERROR code, POLL_BASE_CMD, HEALTH_GET_HEALTH */
} answer_storage_t;

/* GET_BASE_STATUS's two bytes go out as they are in its struct. */
typedef char status_is_two_bytes[offsetof(ctrlbus_get_base_status_answer_t, power_status) == 1u
                                     ? 1
                                     : -1];


/* The answer being written: its storage, and when nothing failed, `size` payload bytes of
 * `source` (usually the storage) through `layout` (NULL: its bytes as they are). */
typedef struct {
    answer_storage_t out;
    const void *source;
    ctrlbus_codec_layout_t layout;
    int32_t size; /* negative: a check refused the handler's struct (0x8002) */
#if CTRLBUS_CONST_IN_FLASH
    bool in_flash; /* source is the application's constant, read through CTRLBUS_READ_CONST */
#endif
} reply_t;

#if CTRLBUS_CONST_IN_FLASH
/* ctrlbus_get_base_conf_answer_size() for an answer in program memory: its two counts read. */
static int32_t base_conf_size_in_flash(const ctrlbus_get_base_conf_answer_t *conf)
{
    uint8_t sensor_num = READ_CONST_BYTE(&conf->sensor_num);
    uint8_t bumper_num = READ_CONST_BYTE(&conf->bumper_num);
    return sensor_num > CTRLBUS_CONF_SLOTS || bumper_num > CTRLBUS_CONF_SLOTS
               ? CTRLBUS_ERR_ARGUMENT
               : (int32_t)CTRLBUS_GET_BASE_CONF_ANSWER_SIZE;
}

/* ctrlbus_codec_put_fields() for a source in program memory: each run of integer fields of
 * `layout` (NULL: `size` bytes as they are), read a byte at a time. Integer fields only: the
 * GET_BASE_CONF answer has no text. */
static NOINLINE void put_const_fields(ctrlbus_sink_t *sink, ctrlbus_codec_layout_t layout,
                                      const void *source, size_t size)
{
    const uint8_t *at = source;
    size_t run = size;
    while (size > 0u) {
        if (layout != NULL) {
            uint8_t shape = CODEC_ROM_BYTE(&layout->shape);
            at = (const uint8_t *)source + CODEC_ROM_BYTE(&layout->offset);
            run = (size_t)(shape >> 2) << (shape & 3u);
            layout++;
        }
        run = run < size ? run : size;
        size -= run;
        for (; run > 0u; run--, at++) {
            uint8_t byte = READ_CONST_BYTE(at);
            ctrlbus_sink_emit(sink, &byte, 1u);
        }
    }
}
#endif

/* Checks a request frame in the order of docs/protocol.md §8.2 (its row of the request table
 * gives the expected length), then runs it: one case per request, each checking its argument
 * value, then whether it is implemented. Returns 0 with *reply set, or the ERROR code to answer.
 * Out of line: its frame is on the stack while it runs, not while the answer is written. */
static NOINLINE uint16_t run_request(ctrlbus_base_t *base, const ctrlbus_frame_t *frame,
                                     reply_t *reply, uint32_t now_ms)
{
    answer_storage_t *out = &reply->out;
    const ctrlbus_base_config_t *config = base->config;
    int32_t result = CTRLBUS_ERR_UNSUPPORTED; /* stays so where a check or the handler lacks */
    int32_t size = 0;
    ctrlbus_codec_layout_t layout = NULL;
    const uint8_t *args = frame->payload;
    size_t len = frame->payload_len;
    uint8_t kind = CTRLBUS_REQ_BASE_CMD;
    size_t expected = CTRLBUS_BASE_CMD_REQUEST_SIZE;
    if (frame->cmd == CTRLBUS_CMD_CTRL_BUS) {
        /* Any CTRL_BUS frame that passed its checksum shows that the Core is alive (§9.1). */
        base->last_feed_ms = now_ms;
        clear_flags(base, FLAG_WATCHDOG_EXPIRED);
        bool health = len != 0u && args[0] == CTRLBUS_CODE_HEALTH_MGMT;
        if (len <= (size_t)health) {
            return CTRLBUS_WIRE_ERR_FORMAT; /* no request code, or HEALTH_MGMT without its sub */
        }
        const ctrlbus_codec_request_layout_t *row = ctrlbus_codec_request_layouts;
        while (CODEC_ROM_BYTE(&row->code) != args[0] ||
               (health && CODEC_ROM_BYTE(&row->subcommand) != args[1])) {
            if (++row == ctrlbus_codec_request_layouts + CTRLBUS_CODEC_REQUEST_LAYOUTS) {
                return health ? CTRLBUS_WIRE_ERR_OPERATION : CTRLBUS_WIRE_ERR_UNSUPPORTED;
            }
        }
        kind = CODEC_ROM_BYTE(&row->kind);
        expected = CODEC_ROM_BYTE(&row->size);
        args += health ? 2 : 1;
    } else if (frame->cmd != CTRLBUS_CMD_BASE_CMD) {
        return CTRLBUS_WIRE_ERR_UNSUPPORTED; /* answer CMDs and reserved ones too */
    }
    if (len != expected) {
        return CTRLBUS_WIRE_ERR_FORMAT;
    }
    memset(out, 0, sizeof *out);
    switch ((ctrlbus_req_kind_t)kind) {
    case CTRLBUS_REQ_BASE_CMD:
        /* Its hook runs once the OK is out (answer()). */
        if ((args[0] == CTRLBUS_BASE_CMD_REBOOT && config->reboot != NULL) ||
            (args[0] == CTRLBUS_BASE_CMD_ENTER_DFU && config->enter_dfu != NULL)) {
            result = CTRLBUS_OK;
        }
        break;
    case CTRLBUS_REQ_CONNECT_BASE:
        if (codec_connect_version_known(args[0]) && config->connect_info != NULL) {
            result = config->connect_info(config->context, &out->connect_base);
            out->connect_base.has_firmware_version_suffix = sdk2020(config); /* the profile's */
            size = ctrlbus_connect_base_answer_size(&out->connect_base);
            layout = ctrlbus_codec_connect_base_layout;
        }
        break;
    case CTRLBUS_REQ_GET_BASE_CONF:
        if (config->base_conf != NULL) {
            result = CTRLBUS_OK; /* streamed from the application's struct: no copy */
            reply->source = config->base_conf;
#if CTRLBUS_CONST_IN_FLASH
            reply->in_flash = true;
            size = base_conf_size_in_flash(config->base_conf);
#else
            size = ctrlbus_get_base_conf_answer_size(config->base_conf);
#endif
            layout = ctrlbus_codec_get_base_conf_layout;
        }
        break;
#if CTRLBUS_CONFIG_CONF_ADV
    case CTRLBUS_REQ_GET_BASE_CONF_ADV:
        if (config->binary_config != NULL && config->binary_config_size != 0u) {
            result = CTRLBUS_OK;
            reply->source = config->binary_config;
#if CTRLBUS_CONST_IN_FLASH
            reply->in_flash = true;
#endif
            size = (int32_t)config->binary_config_size; /* init checked it */
        }
        break;
#endif
    case CTRLBUS_REQ_GET_BASE_STATUS:
        if (config->status != NULL) {
            result = config->status(config->context, &out->get_base_status);
            size = CTRLBUS_GET_BASE_STATUS_ANSWER_SIZE;
        }
        break;
    case CTRLBUS_REQ_GET_BASE_MOTOR_DATA:
        if (config->motor_data != NULL) {
            result = config->motor_data(config->context, &out->get_base_motor_data);
            size = CTRLBUS_GET_BASE_MOTOR_DATA_ANSWER_SIZE_OF(&out->get_base_motor_data);
            layout = ctrlbus_codec_get_base_motor_data_layout;
        }
        break;
    case CTRLBUS_REQ_GET_BASE_SENSOR_DATA:
        if (config->sensor_data != NULL) {
            result = config->sensor_data(config->context, &out->get_base_sensor_data);
            size = CTRLBUS_GET_BASE_SENSOR_DATA_ANSWER_SIZE_OF(&out->get_base_sensor_data);
            layout = ctrlbus_codec_get_base_sensor_data_layout;
        }
        break;
    case CTRLBUS_REQ_GET_BASE_BUMPER_DATA:
        if (config->bumper_data != NULL) {
            result = config->bumper_data(config->context, &out->get_base_bumper_data);
            if (out->get_base_bumper_data.payload_size == 0u || sdk2020(config)) {
                out->get_base_bumper_data.payload_size = CTRLBUS_GET_BASE_BUMPER_DATA_ANSWER_SIZE;
            }
            size = ctrlbus_get_base_bumper_data_answer_size(&out->get_base_bumper_data);
            layout = ctrlbus_codec_get_base_bumper_data_layout;
        }
        break;
    case CTRLBUS_REQ_GET_CHARGER_DATA:
        if (codec_charger_type_known(args[0]) && config->charger_data != NULL) {
            result = config->charger_data(config->context, &out->get_charger_data);
            size = ctrlbus_get_charger_data_answer_size(&out->get_charger_data);
            layout = ctrlbus_codec_get_charger_data_layout;
        }
        break;
    case CTRLBUS_REQ_SET_BASE_MOTOR:
        if (config->set_wheel_speeds != NULL) {
            result = set_wheel_speeds(base, args, out->motion.wheels);
        }
        break;
    case CTRLBUS_REQ_SET_V_AND_GET_DEADRECKON:
        if (config->set_velocity != NULL) {
            result = set_velocity(base, args, &out->motion, now_ms);
            size = CTRLBUS_SET_V_AND_GET_DEADRECKON_ANSWER_SIZE_OF(&out->motion.answer);
            layout = ctrlbus_codec_set_v_and_get_deadreckon_layout;
        }
        break;
    case CTRLBUS_REQ_POLL_BASE_CMD:
        /* The oldest pending command; nothing pending: OK 0 (base_ref v4), or FF 00 for the
         * SDK's fixed-size read. */
        result = CTRLBUS_OK;
        out->bytes[0] = CTRLBUS_POLL_NOTHING_PENDING;
        out->bytes[1] = 0;
#if CTRLBUS_CONFIG_COMMAND_QUEUE
        if (base->command_count != 0u) {
            out->bytes[0] = command_at_head(base);
            size = CTRLBUS_POLL_BASE_CMD_ANSWER_SIZE;
        }
#endif
        if (sdk2020(config)) {
            size = CTRLBUS_POLL_BASE_CMD_ANSWER_SIZE;
        }
        break;
    case CTRLBUS_REQ_POLL_BASE_ANS_CMD:
        result = CTRLBUS_OK;
#if CTRLBUS_CONFIG_COMMAND_QUEUE
        command_taken(base);
#endif
        break;
    case CTRLBUS_REQ_SEND_EVENT:
        result = config->on_event != NULL ? config->on_event(config->context, args[0]) : CTRLBUS_OK;
        break;
    case CTRLBUS_REQ_HEALTH_GET_HEALTH:
        result = CTRLBUS_OK;
        health_summary(base, out->bytes);
        size = CTRLBUS_HEALTH_GET_HEALTH_ANSWER_SIZE;
        break;
    case CTRLBUS_REQ_HEALTH_GET_ERROR:
        /* No such index (or no registry): 0x8002. */
        result = health_entry(base, args[0], &out->health_get_error) ? CTRLBUS_OK
                                                                    : CTRLBUS_ERR_ARGUMENT;
        size = CTRLBUS_HEALTH_GET_ERROR_ANSWER_SIZE;
        layout = ctrlbus_codec_health_get_error_layout;
        break;
    case CTRLBUS_REQ_HEALTH_CLR_ERROR:
        /* Not registered (or no registry): 0x8002. */
        result = ctrlbus_base_health_clear(base, (uint32_t)codec_read_s32(args)) > 0
                     ? CTRLBUS_OK
                     : CTRLBUS_ERR_ARGUMENT;
        break;
    default: break; /* GET_AUXILIARY_ANCHOR, and features compiled out: 0x8000 */
    }
    if (result < 0) {
        return result == CTRLBUS_ERR_UNSUPPORTED ? CTRLBUS_WIRE_ERR_UNSUPPORTED
                                                 : CTRLBUS_WIRE_ERR_OPERATION;
    }
    /* A struct the check refuses (text that is not ASCII, a count over 8, ...) is a handler
     * failure; it is found before any byte goes out. */
    if (size < 0) {
        return CTRLBUS_WIRE_ERR_OPERATION;
    }
    reply->size = size;
    reply->layout = layout;
    return 0;
}

/* Writes the frame of an answer: cmd, the reply's payload, the checksum (long if is_long or if
 * the payload needs it). Out of line: its sink is on the stack only while the answer is written,
 * not while a handler runs. (Inlined into answer() it saves 20-24 B on a Cortex-M0+, but costs
 * 8 B of poll's worst stack there, and 84 B of flash and 28 B of stack on the Uno.) */
static NOINLINE void send(const ctrlbus_base_config_t *config, uint8_t cmd, bool is_long,
                          const reply_t *reply)
{
    ctrlbus_sink_t sink;
    sink.write = config->write; /* the rest is set by start */
    sink.context = config->write_context;
    size_t size = (size_t)reply->size;
    ctrlbus_sink_start(&sink, cmd, size, is_long || size > CTRLBUS_STANDARD_PAYLOAD_MAX);
#if CTRLBUS_CONST_IN_FLASH
    if (reply->in_flash) {
        put_const_fields(&sink, reply->layout, reply->source, size);
    } else
#endif
    {
        ctrlbus_codec_put_fields(&sink, reply->layout, reply->source, size);
    }
    (void)ctrlbus_sink_finish(&sink);
}

/* Writes the one answer to a decoder result: the ERROR for an event (nothing for a timeout),
 * the copy of a SYNC or ECHO request, or a request's OK or ERROR. The one place answers leave;
 * a write callback's failure cuts the answer short, and there is nothing more to say. */
static NOINLINE void answer(ctrlbus_base_t *base, ctrlbus_rx_t rx, const ctrlbus_frame_t *frame,
                            uint32_t now_ms)
{
    reply_t reply;
    reply.source = &reply.out;
    reply.layout = NULL; /* run_request sets it (and size) only when it returns 0 */
#if CTRLBUS_CONST_IN_FLASH
    reply.in_flash = false;
#endif
    uint8_t cmd = CTRLBUS_CMD_OK;
    uint16_t error = 0;
    if (rx != CTRLBUS_RX_FRAME) {
        error = (size_t)rx < sizeof EVENT_ERRORS / sizeof EVENT_ERRORS[0] ? EVENT_ERRORS[rx] : 0u;
        if (error == CTRLBUS_WIRE_ERR_CHECKSUM && base->config->reference_checksum_code) {
            error = CTRLBUS_WIRE_ERR_CHECKSUM_REFERENCE;
        }
        if (error == 0u) {
            return; /* a timeout: nothing to say */
        }
    } else if (frame->cmd <= CTRLBUS_CMD_ECHO) {
        /* SYNC, ECHO: the request copied verbatim, flag and checksum included. */
        cmd = frame->cmd;
        reply.source = frame->payload;
        reply.size = (int32_t)frame->payload_len;
    } else {
        error = run_request(base, frame, &reply, now_ms);
    }
    if (error != 0u) {
        cmd = CTRLBUS_CMD_ERROR;
        reply.out.bytes[0] = (uint8_t)(error & 0xFFu);
        reply.out.bytes[1] = (uint8_t)(error >> 8);
        reply.source = reply.out.bytes;
        reply.size = CTRLBUS_ERROR_ANSWER_SIZE;
#if CTRLBUS_CONST_IN_FLASH
        reply.in_flash = false; /* a refused base_conf */
#endif
    }
    const ctrlbus_base_config_t *config = base->config;
    /* A copy keeps the request's flag; OK and ERROR are long unless standard_answers. */
    send(config, cmd, cmd <= CTRLBUS_CMD_ECHO ? frame->is_long : !config->standard_answers,
         &reply);
    /* A BASE_CMD answered OK: its sub-command's hook (run_request found it), the frame being
     * still where the decoder or the ring holds it. */
    if (cmd == CTRLBUS_CMD_OK && frame->cmd == CTRLBUS_CMD_BASE_CMD) {
        if (frame->payload[0] == CTRLBUS_BASE_CMD_REBOOT) {
            restart(base, now_ms); /* what a handler that returns (a host base) finds */
            config->reboot(config->context);
        } else {
            config->enter_dfu(config->context);
        }
    }
}

/* Feeds the decoder the *run ring bytes from rx_tail on (0: none, which applies the inter-byte
 * timeout at now_ms), up to the first result, which it returns (NONE: none), and sets *run to the
 * bytes it took. A feed appends the bytes of a frame whose size is known in one run and checks
 * them once, when the frame is complete; the base links neither push() nor take(). Out of line:
 * its locals are not on the stack while the answers are written. */
static NOINLINE ctrlbus_rx_t feed_run(ctrlbus_base_t *base, size_t *run, uint32_t now_ms,
                                      ctrlbus_frame_t *frame)
{
    *run = ctrlbus_decoder_feed(&base->decoder, base->config->rx_ring + base->rx_tail, *run, now_ms);
    return ctrlbus_decoder_next(&base->decoder, frame);
}

void ctrlbus_base_poll(ctrlbus_base_t *base, uint32_t now_ms)
{
    if (base == NULL || base->config == NULL) {
        return;
    }
    run_watchdog(base, now_ms);
    /* Only what is in the ring now: an interrupt that keeps feeding cannot keep us here. */
    uint16_t head = base->rx_head;
    CTRLBUS_RING_FENCE(); /* the bytes up to head are read only after head is */
    ctrlbus_frame_t frame;
    /* Each turn handles the ring's bytes from rx_tail (which only poll writes: no copy is kept,
     * which keeps poll's frame small); a poll that finds the ring empty takes one turn of no
     * bytes instead, for the inter-byte timeout. */
    for (;;) {
        const ctrlbus_base_config_t *config = base->config;
        uint16_t tail = base->rx_tail;
        /* The run of bytes up to head or the ring's end; none when the ring is done: a feed of no
         * bytes then applies the inter-byte timeout (what tick() does, without linking it beside
         * feed()), and whatever it leaves is answered. */
        size_t used = 0;
        if (tail != head) {
            used = (size_t)((head > tail ? head : config->rx_ring_size) - tail);
        }
        ctrlbus_rx_t rx = feed_run(base, &used, now_ms, &frame);
        /* The results (rx, then every one the decoder has ready) are answered before their
         * bytes' slots are released. */
        bool found = rx != CTRLBUS_RX_NONE;
        for (; rx != CTRLBUS_RX_NONE; rx = ctrlbus_decoder_next(&base->decoder, &frame)) {
            answer(base, rx, &frame, now_ms);
        }
        if (base->flags & FLAG_REBOOTED) {
            /* A reboot handler returned: restart() dropped the ring's bytes, the answered ones
             * included, and what was received before the reset is not heard. */
            clear_flags(base, FLAG_REBOOTED);
            return;
        }
        tail = (uint16_t)(tail + used);
        if (tail == config->rx_ring_size) {
            tail = 0;
        }
        CTRLBUS_RING_FENCE(); /* done with those bytes before feed may reuse their slots */
        base->rx_tail = tail;
        /* The ring done, so is the poll: after bytes, the decoder's last byte came at now_ms, so
         * no timeout can be due (a turn of no bytes is for a poll that finds the ring empty). A
         * turn that took no byte and found nothing (impossible with a valid decoder) would find
         * nothing again: no spinning. */
        if (tail == head || (used == 0u && !found)) {
            return;
        }
    }
}

/* Whether config asks for a feature that this build compiled out (ctrlbus/ctrlbus_config.h).
 * The tests are OR-ed without short cuts: one test of the sum instead of a branch each. */
static bool needs_missing_feature(const ctrlbus_base_config_t *config)
{
    unsigned missing = 0;
#if !CTRLBUS_CONFIG_HEALTH
    missing |= config->health_entries != NULL;
#endif
#if !CTRLBUS_CONFIG_COMMAND_QUEUE
    missing |= config->command_queue != NULL;
#endif
#if !CTRLBUS_CONFIG_LIMITS
    const ctrlbus_base_limits_t *limits = &config->limits;
    missing |= (limits->max_wheel_mm_s | limits->wheel_track_mm) != 0u;
    missing |= (limits->max_vx_mps_q16 | limits->max_omega_radps_q16) != 0u;
#endif
#if !CTRLBUS_CONFIG_PROFILE_SDK2020
    missing |= config->profile == CTRLBUS_PROFILE_SDK2020;
#endif
#if !CTRLBUS_CONFIG_CONF_ADV
    missing |= config->binary_config != NULL;
#endif
    (void)config;
    return missing != 0u;
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
