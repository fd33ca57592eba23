/* SPDX-License-Identifier: MIT */
/* The base stack under fuzzing, with an oracle for what it answers (see base_harness.h). */
#include "base_harness.h"

#include <string.h>

#include "ctrlbus/base.h"
#include "ctrlbus/diffdrive.h"
#include "ctrlbus/messages.h"

static const size_t FRAME_BUFFERS[8] = {5, 16, 64, 300, 512, 512, 1024, CTRLBUS_FRAME_MAX};
static const uint16_t FRAME_TIMEOUTS[4] = {0, CTRLBUS_BASE_TIMEOUT_OFF, 1, 50};
static const uint32_t WATCHDOGS[4] = {0, CTRLBUS_BASE_WATCHDOG_OFF, 5, 100};

#define RING_SMALL 8u
#define RING_LARGE 1024u
#define HEALTH_CAPACITY 4u
#define COMMAND_QUEUE 3u
/* The limits when the settings ask for them. */
#define MAX_WHEEL_MM_S 500u
#define WHEEL_TRACK_MM 300u
#define MAX_VX_Q16 32768u     /* 0.5 m/s */
#define MAX_OMEGA_Q16 65536u  /* 1 rad/s */
/* Room for what one poll can produce from inputs of up to 64 KiB (fuzz.sh caps them far lower). */
#define OUT_CAP (8u << 20)
#define RESULTS_CAP 80000u
#define POOL_CAP (1u << 18)
#define VERDICTS_CAP 80000u

/* What the base's decoder saw, as the shadow decoder found it. */
typedef struct {
    ctrlbus_rx_t rx;
    bool is_long;
    uint8_t cmd;
    size_t payload_offset; /* into pool */
    size_t payload_len;
} seen_t;

/* What a handler did with the request it was given, in call order. */
typedef enum { VERDICT_OK, VERDICT_FAILED, VERDICT_UNSUPPORTED, VERDICT_BAD_STRUCT } verdict_t;

typedef struct {
    ctrlbus_req_kind_t kind;
    verdict_t verdict;
} handler_call_t;

static struct {
    ctrlbus_base_config_t config;
    ctrlbus_base_t base;
    ctrlbus_decoder_stats_t base_stats;
    fuzz_guarded_t ring;
    fuzz_guarded_t frame_buffer;
    uint8_t shadow_buffer[CTRLBUS_FRAME_MAX];
    uint8_t reader_buffer[CTRLBUS_FRAME_MAX];
    ctrlbus_base_health_entry_t health[HEALTH_CAPACITY];
    uint8_t commands[COMMAND_QUEUE];
    uint8_t probes[8];
    fuzz_rng_t rng;
    bool may_fail;
    uint32_t timeout_ms;
    uint32_t watchdog_ms;

    /* the shadow of the base's decoder, and the bytes the ring took since the last poll */
    ctrlbus_decoder_t shadow;
    uint8_t pending[RING_LARGE];
    size_t pending_len;
    seen_t seen[RESULTS_CAP];
    size_t seen_count;
    uint8_t pool[POOL_CAP];
    size_t pool_used;

    /* what the base wrote during the current poll, and our reader of it */
    uint8_t out[OUT_CAP];
    size_t out_len;
    size_t rebooted_at; /* out_len when the reboot hook ran; SIZE_MAX: it did not */
    ctrlbus_decoder_t reader;

    ctrlbus_get_base_conf_answer_t base_conf; /* config.base_conf */
    handler_call_t calls[VERDICTS_CAP];
    size_t call_count;
    size_t call_next;
    bool line_asserted;
} h;

/* ---- the application's side: handlers ------------------------------------------------------- */

static uint32_t rnd(uint32_t n)
{
    return fuzz_rng_below(&h.rng, n);
}

/* Whether this handler call fails, and how (a struct the codec refuses only where the handler
 * can make one); logged for the oracle. */
static verdict_t decide(ctrlbus_req_kind_t kind, bool can_break)
{
    verdict_t verdict = VERDICT_OK;
    if (h.may_fail && rnd(4) == 0) {
        verdict = (verdict_t)(1u + rnd(can_break ? 3u : 2u));
    }
    FUZZ_CHECK(h.call_count < VERDICTS_CAP);
    h.calls[h.call_count].kind = kind;
    h.calls[h.call_count].verdict = verdict;
    h.call_count++;
    return verdict;
}

static int32_t result_of(verdict_t verdict)
{
    return verdict == VERDICT_FAILED        ? CTRLBUS_ERR_IO
           : verdict == VERDICT_UNSUPPORTED ? CTRLBUS_ERR_UNSUPPORTED
                                            : CTRLBUS_OK;
}

static void ascii_text(char *out, size_t cap, bool broken)
{
    size_t len = rnd((uint32_t)cap); /* up to cap - 1 characters and the NUL */
    for (size_t i = 0; i < len; i++) {
        out[i] = (char)(' ' + rnd(95));
    }
    out[len] = '\0';
    if (broken) {
        out[0] = (char)0xC3; /* not ASCII: the codec refuses it */
        out[1] = '\0';
    }
}

static int32_t on_connect_info(void *context, ctrlbus_connect_base_answer_t *out)
{
    (void)context;
    verdict_t v = decide(CTRLBUS_REQ_CONNECT_BASE, true);
    ascii_text(out->model, sizeof out->model, v == VERDICT_BAD_STRUCT);
    out->firmware_version = (uint16_t)rnd(65536);
    out->hardware_version = (uint16_t)rnd(65536);
    for (size_t i = 0; i < CTRLBUS_SERIAL_WORDS; i++) {
        out->serial[i] = fuzz_rng(&h.rng);
    }
    ascii_text(out->firmware_version_suffix, sizeof out->firmware_version_suffix, false);
    return result_of(v);
}

static void position(ctrlbus_position_t *p)
{
    p->x_mm_q8 = (int32_t)fuzz_rng(&h.rng);
    p->y_mm_q8 = (int32_t)fuzz_rng(&h.rng);
    p->z_mm_q8 = (int32_t)fuzz_rng(&h.rng);
    p->angle_deg_q8 = rnd(360u * 256u);
}

/* GET_BASE_CONF's answer is a struct, not a handler: random but valid, drawn once per run. */
static void draw_base_conf(ctrlbus_get_base_conf_answer_t *out)
{
    out->base_type = (uint8_t)rnd(2);
    out->base_radius_mm_q8 = fuzz_rng(&h.rng);
    out->motor_type = 0;
    out->sensor_num = (uint8_t)rnd(9);
    out->bumper_num = (uint8_t)rnd(9);
    for (size_t i = 0; i < CTRLBUS_CONF_SLOTS; i++) {
        position(&out->sensors[i]);
        position(&out->bumpers[i]);
    }
}

static int32_t on_status(void *context, ctrlbus_get_base_status_answer_t *out)
{
    (void)context;
    verdict_t v = decide(CTRLBUS_REQ_GET_BASE_STATUS, false);
    out->battery_percent = (uint8_t)rnd(101);
    out->power_status = (uint8_t)rnd(8);
    return result_of(v);
}

static int32_t on_motor_data(void *context, ctrlbus_get_base_motor_data_answer_t *out)
{
    (void)context;
    verdict_t v = decide(CTRLBUS_REQ_GET_BASE_MOTOR_DATA, false);
    out->left_distance_mm = (int32_t)fuzz_rng(&h.rng);
    out->right_distance_mm = (int32_t)fuzz_rng(&h.rng);
    out->status = (uint8_t)rnd(8);
    return result_of(v);
}

static int32_t on_sensor_data(void *context, ctrlbus_get_base_sensor_data_answer_t *out)
{
    (void)context;
    verdict_t v = decide(CTRLBUS_REQ_GET_BASE_SENSOR_DATA, false);
    for (size_t i = 0; i < CTRLBUS_SENSOR_CHANNELS; i++) {
        out->distances_mm_q16[i] = fuzz_rng(&h.rng);
    }
    return result_of(v);
}

static int32_t on_bumper_data(void *context, ctrlbus_get_base_bumper_data_answer_t *out)
{
    (void)context;
    verdict_t v = decide(CTRLBUS_REQ_GET_BASE_BUMPER_DATA,
                         h.config.profile != CTRLBUS_PROFILE_SDK2020); /* sdk2020 pads to 4 */;
    out->payload_size = (uint8_t)rnd(5); /* 0: the stack's default, 4 */
    uint32_t bits = out->payload_size == 0 || out->payload_size == 4 ? 32u : 8u * out->payload_size;
    out->bitmap = bits == 32u ? fuzz_rng(&h.rng) : fuzz_rng(&h.rng) & ((1u << bits) - 1u);
    if (v == VERDICT_BAD_STRUCT) {
        out->payload_size = 1;
        out->bitmap = 0x100u; /* does not fit in one byte */
    }
    return result_of(v);
}

static int32_t on_charger_data(void *context, ctrlbus_get_charger_data_answer_t *out)
{
    (void)context;
    verdict_t v = decide(CTRLBUS_REQ_GET_CHARGER_DATA, true);
    out->beacon_count = (uint8_t)rnd(4);
    out->probe_count = (uint8_t)rnd(4);
    for (size_t i = 0; i < sizeof h.probes; i++) {
        h.probes[i] = (uint8_t)rnd(256);
    }
    out->probes = v == VERDICT_BAD_STRUCT ? NULL : h.probes;
    if (v == VERDICT_BAD_STRUCT) {
        out->probe_count = 2; /* probes missing */
    }
    return result_of(v);
}

static uint32_t magnitude(int32_t value)
{
    return value < 0 ? 0u - (uint32_t)value : (uint32_t)value;
}

static int32_t on_set_wheel_speeds(void *context, int32_t left_mm_s, int32_t right_mm_s)
{
    (void)context;
    /* Also the watchdog's stop when there is no stop_motors: no verdict logged here. */
    if (h.config.limits.max_wheel_mm_s != 0) {
        FUZZ_CHECK(magnitude(left_mm_s) <= h.config.limits.max_wheel_mm_s);
        FUZZ_CHECK(magnitude(right_mm_s) <= h.config.limits.max_wheel_mm_s);
    }
    return h.may_fail && rnd(8) == 0 ? CTRLBUS_ERR_IO : CTRLBUS_OK;
}

static int32_t on_set_velocity(void *context,
                               const ctrlbus_set_v_and_get_deadreckon_request_t *velocity,
                               ctrlbus_set_v_and_get_deadreckon_answer_t *out)
{
    (void)context;
    verdict_t v = decide(CTRLBUS_REQ_SET_V_AND_GET_DEADRECKON, false);
    const ctrlbus_base_limits_t *limits = &h.config.limits;
    if (limits->max_vx_mps_q16 != 0) {
        FUZZ_CHECK(magnitude(velocity->vx_mps_q16) <= limits->max_vx_mps_q16);
    }
    if (limits->max_omega_radps_q16 != 0) {
        FUZZ_CHECK(magnitude(velocity->omega_radps_q16) <= limits->max_omega_radps_q16);
    }
    if (limits->wheel_track_mm != 0 && limits->max_wheel_mm_s != 0) {
        int32_t left = 0;
        int32_t right = 0;
        ctrlbus_diffdrive_wheel_speeds(velocity->vx_mps_q16, velocity->omega_radps_q16,
                                       limits->wheel_track_mm, &left, &right);
        /* The limit holds up to the rounding of the wheel speeds to whole mm/s. */
        FUZZ_CHECK(magnitude(left) <= limits->max_wheel_mm_s + 1u);
        FUZZ_CHECK(magnitude(right) <= limits->max_wheel_mm_s + 1u);
    }
    out->dx_mm_q16 = (int32_t)fuzz_rng(&h.rng);
    out->dy_mm_q16 = (int32_t)fuzz_rng(&h.rng);
    out->dtheta_deg_q16 = (int32_t)fuzz_rng(&h.rng);
    out->status = (uint8_t)rnd(8);
    out->has_timestamp_ms = rnd(2) == 0;
    out->timestamp_ms = fuzz_rng(&h.rng);
    return result_of(v);
}

static void on_stop_motors(void *context)
{
    (void)context;
}

static int32_t on_event(void *context, uint8_t event)
{
    (void)context;
    (void)event;
    verdict_t v = decide(CTRLBUS_REQ_SEND_EVENT, false);
    return result_of(v);
}

static void on_reboot(void *context)
{
    (void)context;
    FUZZ_CHECK(h.rebooted_at == SIZE_MAX); /* the poll ends with the reboot */
    h.rebooted_at = h.out_len;
}

static void on_enter_dfu(void *context)
{
    (void)context;
}

static void on_command_line(void *context, bool asserted)
{
    (void)context;
    FUZZ_CHECK(asserted != h.line_asserted); /* it reports changes */
    FUZZ_CHECK(asserted == (ctrlbus_base_commands_pending(&h.base) != 0));
    h.line_asserted = asserted;
}

static int32_t on_write(void *context, const uint8_t *data, size_t len)
{
    (void)context;
    FUZZ_CHECK(h.rebooted_at == SIZE_MAX); /* nothing after the reboot hook */
    FUZZ_CHECK(len <= OUT_CAP - h.out_len);
    memcpy(h.out + h.out_len, data, len);
    h.out_len += len;
    return CTRLBUS_OK;
}

/* ---- the oracle ------------------------------------------------------------------------------ */

static void remember(ctrlbus_rx_t rx, const ctrlbus_frame_t *frame)
{
    FUZZ_CHECK(h.seen_count < RESULTS_CAP);
    seen_t *s = &h.seen[h.seen_count++];
    s->rx = rx;
    s->payload_len = 0;
    if (rx == CTRLBUS_RX_FRAME) {
        FUZZ_CHECK(frame->payload_len <= POOL_CAP - h.pool_used);
        s->is_long = frame->is_long;
        s->cmd = frame->cmd;
        s->payload_offset = h.pool_used;
        s->payload_len = frame->payload_len;
        memcpy(h.pool + h.pool_used, frame->payload, frame->payload_len);
        h.pool_used += frame->payload_len;
    }
}

static void shadow_drain(void)
{
    ctrlbus_frame_t frame;
    for (ctrlbus_rx_t rx; (rx = ctrlbus_decoder_next(&h.shadow, &frame)) != CTRLBUS_RX_NONE;) {
        remember(rx, &frame);
    }
}

/* The shadow takes what the base's poll took: the ring's bytes at the poll's time, then a tick. */
static void shadow_poll(uint32_t now_ms)
{
    h.seen_count = 0;
    h.pool_used = 0;
    for (size_t i = 0; i < h.pending_len;) {
        i += ctrlbus_decoder_feed(&h.shadow, h.pending + i, h.pending_len - i, now_ms);
        shadow_drain();
    }
    h.pending_len = 0;
    ctrlbus_decoder_tick(&h.shadow, now_ms);
    shadow_drain();
}

static uint16_t error_code_of(const ctrlbus_frame_t *answer)
{
    FUZZ_CHECK(answer->cmd == CTRLBUS_CMD_ERROR && answer->payload_len == 2);
    return (uint16_t)(answer->payload[0] | (answer->payload[1] << 8));
}

static void check_frame_type(const ctrlbus_frame_t *answer)
{
    if (h.config.standard_answers) {
        FUZZ_CHECK(answer->is_long == (answer->payload_len > CTRLBUS_STANDARD_PAYLOAD_MAX));
    } else {
        FUZZ_CHECK(answer->is_long);
    }
}

/* Which handler (logged with a verdict) answers a request kind in this harness's config. */
static bool has_logged_handler(ctrlbus_req_kind_t kind)
{
    switch (kind) {
    case CTRLBUS_REQ_CONNECT_BASE:
    case CTRLBUS_REQ_GET_BASE_STATUS:
    case CTRLBUS_REQ_GET_BASE_MOTOR_DATA:
    case CTRLBUS_REQ_GET_BASE_SENSOR_DATA:
    case CTRLBUS_REQ_GET_BASE_BUMPER_DATA:
    case CTRLBUS_REQ_GET_CHARGER_DATA:
    case CTRLBUS_REQ_SET_V_AND_GET_DEADRECKON:
    case CTRLBUS_REQ_SEND_EVENT: return true;
    default: return false;
    }
}

/* The OK payload sizes the profile fixes. */
static void check_profile_sizes(ctrlbus_req_kind_t kind, const ctrlbus_frame_t *answer)
{
    bool sdk2020 = h.config.profile == CTRLBUS_PROFILE_SDK2020;
    switch (kind) {
    case CTRLBUS_REQ_CONNECT_BASE: FUZZ_CHECK(answer->payload_len == (sdk2020 ? 39u : 28u)); break;
    case CTRLBUS_REQ_SET_V_AND_GET_DEADRECKON:
        FUZZ_CHECK(answer->payload_len == (sdk2020 ? 17u : 13u));
        break;
    case CTRLBUS_REQ_GET_BASE_BUMPER_DATA:
        FUZZ_CHECK(!sdk2020 || answer->payload_len == 4u);
        break;
    case CTRLBUS_REQ_POLL_BASE_CMD:
        FUZZ_CHECK(answer->payload_len == 2u || (!sdk2020 && answer->payload_len == 0u));
        break;
    default: break;
    }
}

/* One request frame and the answer the base gave it. Returns true when it was a REBOOT that the
 * base carried out (then nothing follows in this poll). */
static bool check_request(const seen_t *s, const ctrlbus_frame_t *answer)
{
    const uint8_t *payload = h.pool + s->payload_offset;
    if (s->cmd == CTRLBUS_CMD_SYNC || s->cmd == CTRLBUS_CMD_ECHO) {
        FUZZ_CHECK(answer->cmd == s->cmd && answer->is_long == s->is_long);
        FUZZ_CHECK(answer->payload_len == s->payload_len);
        FUZZ_CHECK(s->payload_len == 0 || memcmp(answer->payload, payload, s->payload_len) == 0);
        return false;
    }
    check_frame_type(answer);
    ctrlbus_request_t request;
    int32_t decoded = ctrlbus_request_decode(&request, s->cmd, payload, s->payload_len);
    if (decoded < 0) {
        FUZZ_CHECK(error_code_of(answer) == ctrlbus_request_error_code(&request, decoded));
        return false;
    }
    if (has_logged_handler(request.kind)) {
        FUZZ_CHECK(h.call_next < h.call_count);
        const handler_call_t *call = &h.calls[h.call_next++];
        FUZZ_CHECK(call->kind == request.kind); /* the right handler, in order */
        switch (call->verdict) {
        case VERDICT_OK: FUZZ_CHECK(answer->cmd == CTRLBUS_CMD_OK); break;
        case VERDICT_UNSUPPORTED:
            FUZZ_CHECK(error_code_of(answer) == CTRLBUS_WIRE_ERR_UNSUPPORTED);
            break;
        default: FUZZ_CHECK(error_code_of(answer) == CTRLBUS_WIRE_ERR_OPERATION); break;
        }
    }
    if (answer->cmd != CTRLBUS_CMD_OK) {
        uint16_t code = error_code_of(answer);
        FUZZ_CHECK(code == CTRLBUS_WIRE_ERR_UNSUPPORTED || code == CTRLBUS_WIRE_ERR_OPERATION);
        return false;
    }
    ctrlbus_answer_t decoded_answer;
    FUZZ_CHECK(ctrlbus_answer_decode(&decoded_answer, request.kind, answer->cmd, answer->payload,
                                     answer->payload_len) == CTRLBUS_OK);
    check_profile_sizes(request.kind, answer);
    return request.kind == CTRLBUS_REQ_BASE_CMD &&
           request.as.base_cmd.subcommand == CTRLBUS_BASE_CMD_REBOOT;
}

static void check_event(ctrlbus_rx_t rx, const ctrlbus_frame_t *answer)
{
    uint16_t expected = 0;
    switch (rx) {
    case CTRLBUS_RX_GARBAGE: expected = CTRLBUS_WIRE_ERR_NOT_SYNCHRONISED; break;
    case CTRLBUS_RX_CHECKSUM_ERROR:
        expected = h.config.reference_checksum_code ? CTRLBUS_WIRE_ERR_CHECKSUM_REFERENCE
                                                    : CTRLBUS_WIRE_ERR_CHECKSUM;
        break;
    case CTRLBUS_RX_OVERSIZE: expected = CTRLBUS_WIRE_ERR_TOO_LONG; break;
    case CTRLBUS_RX_EMPTY_FRAME: expected = CTRLBUS_WIRE_ERR_FORMAT; break;
    default: FUZZ_CHECK(false);
    }
    check_frame_type(answer);
    FUZZ_CHECK(error_code_of(answer) == expected);
}

/* Reads back what the poll wrote and pairs it with what the shadow saw. */
static void check_answers(void)
{
    bool rebooted = h.rebooted_at != SIZE_MAX;
    FUZZ_CHECK(!rebooted || h.rebooted_at == h.out_len);
    ctrlbus_decoder_stats_t stats;
    FUZZ_CHECK(ctrlbus_decoder_init(&h.reader, h.reader_buffer, CTRLBUS_FRAME_MAX, 0, &stats) ==
               CTRLBUS_OK);
    size_t next_seen = 0;
    bool reboot_done = false;
    for (size_t pos = 0; pos < h.out_len;) {
        pos += ctrlbus_decoder_feed(&h.reader, h.out + pos, h.out_len - pos, 0);
        ctrlbus_frame_t answer;
        for (ctrlbus_rx_t rx; (rx = ctrlbus_decoder_next(&h.reader, &answer)) != CTRLBUS_RX_NONE;) {
            FUZZ_CHECK(rx == CTRLBUS_RX_FRAME); /* answers are whole, valid frames */
            FUZZ_CHECK(!reboot_done);
            while (next_seen < h.seen_count && h.seen[next_seen].rx == CTRLBUS_RX_TIMEOUT) {
                next_seen++; /* a partial frame cut by the timeout is not answered */
            }
            FUZZ_CHECK(next_seen < h.seen_count); /* no answer without a request or event */
            const seen_t *s = &h.seen[next_seen++];
            if (s->rx == CTRLBUS_RX_FRAME) {
                reboot_done = check_request(s, &answer);
                FUZZ_CHECK(!reboot_done || rebooted); /* a REBOOT answered OK runs the hook */
            } else {
                check_event(s->rx, &answer);
            }
        }
    }
    FUZZ_CHECK(!ctrlbus_decoder_busy(&h.reader) && stats.bytes_discarded == 0);
    FUZZ_CHECK(reboot_done == rebooted);
    if (rebooted) {
        /* The base dropped what it had not read and restarted its decoder: so does the shadow. */
        ctrlbus_decoder_reset(&h.shadow);
        h.call_next = h.call_count; /* and the handlers' calls for dropped requests (none) */
        return;
    }
    while (next_seen < h.seen_count && h.seen[next_seen].rx == CTRLBUS_RX_TIMEOUT) {
        next_seen++;
    }
    FUZZ_CHECK(next_seen == h.seen_count); /* every request and event was answered */
    FUZZ_CHECK(h.call_next == h.call_count);
}

/* ---- driving the base ------------------------------------------------------------------------ */

void base_harness_poll(uint32_t now_ms)
{
    h.out_len = 0;
    h.rebooted_at = SIZE_MAX;
    ctrlbus_base_poll(&h.base, now_ms);
    fuzz_guarded_check(&h.ring);
    fuzz_guarded_check(&h.frame_buffer);
    shadow_poll(now_ms);
    check_answers();
    FUZZ_CHECK(h.line_asserted == (ctrlbus_base_commands_pending(&h.base) != 0));
}

void base_harness_feed(const uint8_t *data, size_t len, uint32_t now_ms)
{
    while (len > 0) {
        size_t taken = ctrlbus_base_feed(&h.base, data, len);
        FUZZ_CHECK(taken <= len && h.pending_len + taken <= sizeof h.pending);
        memcpy(h.pending + h.pending_len, data, taken);
        h.pending_len += taken;
        data += taken;
        len -= taken;
        if (len > 0) {
            base_harness_poll(now_ms); /* the ring is full: let the main loop empty it */
        }
    }
}

void base_harness_queue_command(uint8_t code)
{
    uint8_t before = ctrlbus_base_commands_pending(&h.base);
    int32_t result = ctrlbus_base_queue_command(&h.base, code);
    uint8_t after = ctrlbus_base_commands_pending(&h.base);
    FUZZ_CHECK(result == CTRLBUS_OK ? after == before + 1u : after == before);
    FUZZ_CHECK(h.line_asserted == (after != 0));
}

uint32_t base_harness_timeout_ms(void)
{
    return h.timeout_ms;
}

uint32_t base_harness_watchdog_ms(void)
{
    return h.watchdog_ms;
}

static const uint32_t HEALTH_CODES[3] = {CTRLBUS_HEALTH_WATCHDOG_TRIPPED, 0x01020000u, 0x04050001u};
static const char *const HEALTH_MESSAGES[3] = {"motor watchdog tripped", "low battery", ""};

/* Stands for a blob in flash: any bytes. */
static const uint8_t BINARY_CONFIG[] = {0x43, 0x42, 0x43, 0x46, 0x01, 0x00, 0x10, 0x50, 0x00, 0xFF};

void base_harness_start(fuzz_input_t *in, uint32_t now_ms)
{
    uint8_t s0 = fuzz_u8(in);
    uint8_t s1 = fuzz_u8(in);
    fuzz_rng_seed(&h.rng, fuzz_u16(in));
    size_t frame_buffer_size = FRAME_BUFFERS[s0 & 7u];
    uint16_t ring_size = (s0 & 0x80u) ? RING_SMALL : RING_LARGE;
    fuzz_guarded_init(&h.ring, ring_size);
    fuzz_guarded_init(&h.frame_buffer, frame_buffer_size);

    ctrlbus_base_config_t *c = &h.config;
    memset(c, 0, sizeof *c);
    c->rx_ring = h.ring.buffer;
    c->rx_ring_size = ring_size;
    c->frame_buffer = h.frame_buffer.buffer;
    c->frame_buffer_size = frame_buffer_size;
    c->decoder_stats = &h.base_stats;
    switch ((s0 >> 3) & 3u) {
    case 1: c->standard_answers = true; break;
    case 2: c->profile = CTRLBUS_PROFILE_SDK2020; break;
    case 3: c->reference_checksum_code = true; break;
    default: break;
    }
    if (s0 & 0x20u) {
        c->limits.max_wheel_mm_s = MAX_WHEEL_MM_S;
        c->limits.wheel_track_mm = (uint16_t)(fuzz_rng_below(&h.rng, 2) ? WHEEL_TRACK_MM : 0u);
        c->limits.max_vx_mps_q16 = MAX_VX_Q16;
        c->limits.max_omega_radps_q16 = MAX_OMEGA_Q16;
    }
    h.may_fail = (s0 & 0x40u) != 0;
    c->frame_timeout_ms = FRAME_TIMEOUTS[s1 & 3u];
    c->watchdog_ms = WATCHDOGS[(s1 >> 2) & 3u];
    if (s1 & 0x10u) {
        c->health_entries = h.health;
        c->health_capacity = HEALTH_CAPACITY;
        c->command_queue = h.commands;
        c->command_queue_size = COMMAND_QUEUE;
    }
    if (s1 & 0x20u) {
        c->binary_config = BINARY_CONFIG;
        c->binary_config_size = sizeof BINARY_CONFIG;
    }
    if (s1 & 0x40u) {
        c->reboot = on_reboot;
        c->enter_dfu = on_enter_dfu;
    }
    if (s1 & 0x80u) {
        c->stop_motors = on_stop_motors;
    }
    c->write = on_write;
    c->connect_info = on_connect_info;
    draw_base_conf(&h.base_conf);
    c->base_conf = &h.base_conf;
    c->status = on_status;
    c->motor_data = on_motor_data;
    c->sensor_data = on_sensor_data;
    c->bumper_data = on_bumper_data;
    c->charger_data = on_charger_data;
    c->set_wheel_speeds = on_set_wheel_speeds;
    c->set_velocity = on_set_velocity;
    c->on_event = on_event;
    c->command_line = on_command_line;

    h.timeout_ms = c->frame_timeout_ms == 0                          ? CTRLBUS_DEFAULT_TIMEOUT_MS
                   : c->frame_timeout_ms == CTRLBUS_BASE_TIMEOUT_OFF ? 0u
                                                                     : c->frame_timeout_ms;
    h.watchdog_ms = c->watchdog_ms == 0                          ? CTRLBUS_BASE_DEFAULT_WATCHDOG_MS
                    : c->watchdog_ms == CTRLBUS_BASE_WATCHDOG_OFF ? 0u
                                                                  : c->watchdog_ms;
    h.pending_len = 0;
    h.call_count = h.call_next = 0;
    h.line_asserted = false;
    FUZZ_CHECK(ctrlbus_base_init(&h.base, c, now_ms) == CTRLBUS_OK);
    /* The application may have registered health errors (the first code is the watchdog's, and
     * the first two are in the vectors, so that HEALTH_CLR_ERROR seeds find them). */
    for (uint32_t i = 0, n = rnd(4); i < n; i++) {
        int32_t added = ctrlbus_base_health_add(&h.base, HEALTH_CODES[i], HEALTH_MESSAGES[i]);
        FUZZ_CHECK(added == 1 || (c->health_entries == NULL && added == CTRLBUS_ERR_TOO_BIG));
    }

    FUZZ_CHECK(ctrlbus_decoder_init(&h.shadow, h.shadow_buffer, frame_buffer_size,
                                    (uint16_t)h.timeout_ms, NULL) == CTRLBUS_OK);
}

void base_harness_finish(uint32_t now_ms)
{
    base_harness_poll(now_ms);
    /* Long after the last byte: a partial request has timed out, the watchdog has run. */
    base_harness_poll(now_ms + h.timeout_ms + h.watchdog_ms + 1u);
    if (h.timeout_ms != 0) {
        FUZZ_CHECK(!ctrlbus_decoder_busy(&h.shadow));
    }
}
