/* SPDX-License-Identifier: MIT */
/* Frame layer: streaming encoder and streaming decoder (see ctrlbus/frame.h). */
#include "ctrlbus/frame.h"

#include <string.h>

#include "codec.h"

/* ---- shared --------------------------------------------------------------------------------- */

/* Lives here because the frame layer is the lowest one every program links. */
const char *ctrlbus_error_name(int32_t error)
{
    switch (error) {
    case CTRLBUS_OK: return "ok";
    case CTRLBUS_ERR_ARGUMENT: return "argument";
    case CTRLBUS_ERR_FORMAT: return "format";
    case CTRLBUS_ERR_UNSUPPORTED: return "unsupported";
    case CTRLBUS_ERR_TOO_BIG: return "too_big";
    case CTRLBUS_ERR_LENGTH: return "length";
    case CTRLBUS_ERR_IO: return "io";
    default: return "unknown";
    }
}

static uint8_t xor_bytes(uint8_t checksum, const uint8_t *data, size_t len)
{
    for (size_t i = 0; i < len; i++) {
        checksum ^= data[i];
    }
    return checksum;
}

/* ---- encoder -------------------------------------------------------------------------------- */

int32_t ctrlbus_frame_size(size_t payload_len, ctrlbus_frame_type_t type)
{
    switch (type) {
    case CTRLBUS_FRAME_AUTO:
        if (payload_len <= CTRLBUS_STANDARD_PAYLOAD_MAX) {
            return (int32_t)(payload_len + CTRLBUS_STANDARD_OVERHEAD);
        }
        return ctrlbus_frame_size(payload_len, CTRLBUS_FRAME_LONG);
    case CTRLBUS_FRAME_STANDARD:
        if (payload_len > CTRLBUS_STANDARD_PAYLOAD_MAX) {
            return CTRLBUS_ERR_TOO_BIG;
        }
        return (int32_t)(payload_len + CTRLBUS_STANDARD_OVERHEAD);
    case CTRLBUS_FRAME_LONG:
        if (payload_len > CTRLBUS_LONG_PAYLOAD_MAX) {
            return CTRLBUS_ERR_TOO_BIG;
        }
        return (int32_t)(payload_len + CTRLBUS_LONG_OVERHEAD);
    default: return CTRLBUS_ERR_ARGUMENT;
    }
}

int32_t ctrlbus_sink_init(ctrlbus_sink_t *sink, ctrlbus_write_fn write, void *context)
{
    if (sink == NULL || write == NULL) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    sink->write = write;
    sink->context = context;
    sink->remaining = 0;
    sink->frame_len = 0;
    sink->status = CTRLBUS_OK;
    sink->checksum = 0;
    sink->in_frame = 0;
    return CTRLBUS_OK;
}

/* The sink's unchecked core (codec.h): the public functions below check, then call these; the
 * base stack, whose answers are right by construction, calls them directly. Every byte of a frame
 * goes out through ctrlbus_sink_emit(), the header and the checksum too (each announced in
 * `remaining` just before): one function holds the write call, so the write path is shallow. */

void ctrlbus_sink_start(ctrlbus_sink_t *sink, uint8_t cmd, size_t payload_len, bool is_long)
{
    size_t len_field = payload_len + 1u; /* payload_len <= 65534: exact below */
    size_t header_len = is_long ? 4u : 3u;
    uint8_t header[4];
    header[0] = is_long ? CTRLBUS_FLAG_LONG : CTRLBUS_FLAG_STANDARD;
    header[1] = (uint8_t)(len_field & 0xFFu);
    header[2] = (uint8_t)(len_field >> 8); /* a long frame's; a standard one's cmd goes here */
    header[header_len - 1u] = cmd;
    sink->status = CTRLBUS_OK;
    sink->checksum = 0;
    sink->remaining = (uint16_t)header_len;
    ctrlbus_sink_emit(sink, header, header_len);
    sink->remaining = (uint16_t)payload_len;
}

void ctrlbus_sink_emit(ctrlbus_sink_t *sink, const uint8_t *data, size_t len)
{
    int32_t error = CTRLBUS_ERR_LENGTH; /* more than announced (remaining is 0 outside a frame) */
    if (len <= sink->remaining) {
        sink->remaining = (uint16_t)(sink->remaining - len);
        if (sink->status != CTRLBUS_OK || len == 0) {
            return;
        }
        /* (taken before the write: after a failed write the checksum is never written) */
        sink->checksum = xor_bytes(sink->checksum, data, len);
        error = sink->write(sink->context, data, len);
    }
    if (error < 0 && sink->status == CTRLBUS_OK) {
        sink->status = error; /* so nothing more is written */
    }
}

int32_t ctrlbus_sink_finish(ctrlbus_sink_t *sink)
{
    size_t payload_left = sink->remaining;
    uint8_t checksum = sink->checksum;
    sink->remaining = 1; /* the checksum, which emit folds into itself: it is not read again */
    /* A frame short of its announced payload asks for more than the one byte: LENGTH, and
     * nothing is written (emit reads no byte then). */
    ctrlbus_sink_emit(sink, &checksum, payload_left + 1u);
    return sink->status;
}

int32_t ctrlbus_sink_begin(ctrlbus_sink_t *sink, uint8_t cmd, size_t payload_len,
                           ctrlbus_frame_type_t type)
{
    if (sink == NULL || sink->write == NULL) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    sink->in_frame = 0;
    sink->remaining = 0;
    int32_t frame_len = ctrlbus_frame_size(payload_len, type);
    if (frame_len < 0) {
        sink->status = frame_len;
        return frame_len;
    }
    bool is_long = type == CTRLBUS_FRAME_LONG ||
                   (type == CTRLBUS_FRAME_AUTO && payload_len > CTRLBUS_STANDARD_PAYLOAD_MAX);
    ctrlbus_sink_start(sink, cmd, payload_len, is_long);
    sink->frame_len = (uint32_t)frame_len;
    sink->in_frame = 1;
    return sink->status;
}

void ctrlbus_sink_fail(ctrlbus_sink_t *sink, int32_t error)
{
    if (sink != NULL && sink->status == CTRLBUS_OK && error < 0) {
        sink->status = error;
    }
}

void ctrlbus_sink_put(ctrlbus_sink_t *sink, const uint8_t *data, size_t len)
{
    if (sink == NULL || len == 0) {
        return;
    }
    if (data == NULL) {
        ctrlbus_sink_fail(sink, CTRLBUS_ERR_ARGUMENT);
        return;
    }
    ctrlbus_sink_emit(sink, data, len);
}

void ctrlbus_sink_put_u8(ctrlbus_sink_t *sink, uint8_t value)
{
    ctrlbus_sink_put(sink, &value, 1);
}

void ctrlbus_sink_put_u16(ctrlbus_sink_t *sink, uint16_t value)
{
    uint8_t bytes[2] = {(uint8_t)(value & 0xFFu), (uint8_t)(value >> 8)};
    ctrlbus_sink_put(sink, bytes, sizeof bytes);
}

void ctrlbus_sink_put_u32(ctrlbus_sink_t *sink, uint32_t value)
{
    uint8_t bytes[4] = {(uint8_t)(value & 0xFFu), (uint8_t)((value >> 8) & 0xFFu),
                        (uint8_t)((value >> 16) & 0xFFu), (uint8_t)(value >> 24)};
    ctrlbus_sink_put(sink, bytes, sizeof bytes);
}

void ctrlbus_sink_put_s32(ctrlbus_sink_t *sink, int32_t value)
{
    ctrlbus_sink_put_u32(sink, (uint32_t)value); /* two's complement on the wire */
}

void ctrlbus_sink_put_text(ctrlbus_sink_t *sink, const char *text, size_t field_size)
{
    size_t text_len = 0;
    if (text != NULL) {
        while (text_len < field_size && text[text_len] != '\0') {
            text_len++;
        }
        ctrlbus_sink_put(sink, (const uint8_t *)text, text_len);
    }
    static const uint8_t zeros[8] = {0};
    for (size_t left = field_size - text_len; left > 0;) {
        size_t piece = left < sizeof zeros ? left : sizeof zeros;
        ctrlbus_sink_put(sink, zeros, piece);
        left -= piece;
    }
}

int32_t ctrlbus_sink_end(ctrlbus_sink_t *sink)
{
    if (sink == NULL) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    if (!sink->in_frame) {
        ctrlbus_sink_fail(sink, CTRLBUS_ERR_LENGTH); /* no checksum is written then */
    }
    sink->in_frame = 0;
    int32_t result = ctrlbus_sink_finish(sink);
    return result < 0 ? result : (int32_t)sink->frame_len;
}

int32_t ctrlbus_buffer_write(void *context, const uint8_t *data, size_t len)
{
    ctrlbus_buffer_t *buffer = context;
    if (buffer == NULL || (data == NULL && len > 0)) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    if (len > buffer->size - buffer->len) {
        return CTRLBUS_ERR_TOO_BIG;
    }
    if (len > 0) {
        memcpy(buffer->data + buffer->len, data, len);
        buffer->len += len;
    }
    return CTRLBUS_OK;
}

int32_t ctrlbus_sink_init_buffer(ctrlbus_sink_t *sink, ctrlbus_buffer_t *buffer, uint8_t *data,
                                 size_t size)
{
    if (buffer == NULL || (data == NULL && size > 0)) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    buffer->data = data;
    buffer->size = size;
    buffer->len = 0;
    return ctrlbus_sink_init(sink, ctrlbus_buffer_write, buffer);
}

int32_t ctrlbus_frame_write(ctrlbus_sink_t *sink, uint8_t cmd, const uint8_t *payload,
                            size_t payload_len, ctrlbus_frame_type_t type)
{
    int32_t result = ctrlbus_sink_begin(sink, cmd, payload_len, type);
    if (result < 0) {
        return result;
    }
    ctrlbus_sink_put(sink, payload, payload_len);
    return ctrlbus_sink_end(sink);
}

int32_t ctrlbus_frame_encode(uint8_t *out, size_t out_size, uint8_t cmd, const uint8_t *payload,
                             size_t payload_len, ctrlbus_frame_type_t type)
{
    ctrlbus_sink_t sink;
    ctrlbus_buffer_t buffer;
    int32_t frame_len = ctrlbus_frame_size(payload_len, type);
    if (frame_len < 0) {
        return frame_len;
    }
    if ((size_t)frame_len > out_size) {
        return CTRLBUS_ERR_TOO_BIG; /* checked first so that nothing is half-written */
    }
    int32_t result = ctrlbus_sink_init_buffer(&sink, &buffer, out, out_size);
    if (result < 0) {
        return result;
    }
    return ctrlbus_frame_write(&sink, cmd, payload, payload_len, type);
}

/* ---- decoder -------------------------------------------------------------------------------- */

/* The bulk path's level, CTRLBUS_DECODER_FAST, is set in ctrlbus/ctrlbus_config.h. */
#if CTRLBUS_DECODER_FAST == 1
#define DECODER_SHORTCUTS 1
#else
#define DECODER_SHORTCUTS 0
#endif

/* Inlining hints for the bulk path, for GCC and clang (other compilers decide alone; without the
 * bulk path, or optimising for size, the compiler decides too). OUT_OF_LINE keeps a rarer path in
 * its own function so that its caller's common path saves no registers it does not need; IN_LINE
 * copies a short step of the bulk path into each caller. */
#if CTRLBUS_DECODER_FAST && defined(__GNUC__) && !defined(__OPTIMIZE_SIZE__)
#define OUT_OF_LINE __attribute__((noinline))
#define IN_LINE __inline__ __attribute__((always_inline))
#else
#define OUT_OF_LINE
#define IN_LINE
#endif
/* For a rare path, at every optimisation level: kept out of its caller, which then stays small. */
#if defined(__GNUC__)
#define RARE __attribute__((noinline))
#else
#define RARE
#endif

/* decoder->state: the low three bits hold a result found but not yet taken by next(). */
#define STATE_PENDING_MASK 0x07u
/* An event has been raised since the last yielded frame: garbage stays quiet until a frame. */
#define STATE_EVENT_SINCE_FRAME 0x08u
/* Scanning must restart at `start` (after a result was taken) instead of continuing at `end`. */
#define STATE_RESCAN 0x10u
/* A timeout is being applied: rescanned candidates that are incomplete fail at once. */
#define STATE_FLUSHING 0x20u
/* The scan position lies in the span of a failed candidate (rule 4), so events are silent. One bit
 * is enough: a failure makes every buffered byte its span, and bytes that arrive later are only
 * looked at as part of a candidate that started inside the span; that candidate either fails
 * (a new span of everything buffered) or completes exactly at the end of the buffer, which then
 * runs empty. So the position is in a span exactly while the buffer has not run empty since the
 * last failure. */
#define STATE_IN_SPAN 0x40u
/* ctrlbus_decoder_push() took a byte while a timeout applied before it: the byte waits at
 * buffer[end] (outside the buffered bytes; without the bulk path, in d->checksum) until the
 * results of the timeout have been taken. */
#define STATE_HELD 0x80u
/* Results or work that must come before any new byte. */
#define STATE_WAITING (STATE_PENDING_MASK | STATE_RESCAN | STATE_HELD)
/* frame.h's inline push relies on the same values. */
typedef char frame_h_state_bits_match[(STATE_WAITING == CTRLBUS_DECODER_WAITING_ &&
                                       STATE_EVENT_SINCE_FRAME == CTRLBUS_DECODER_EVENT_SINCE_FRAME_ &&
                                       (STATE_EVENT_SINCE_FRAME | STATE_FLUSHING | STATE_IN_SPAN) ==
                                           CTRLBUS_DECODER_EMPTY_CLEARS_)
                                          ? 1
                                          : -1];

/* Time gaps at or beyond this are taken as "the clock went backwards" rather than a long wait. */
#define TIME_BACKWARDS 0x80000000u

/* Between calls, either a result waits to be handed out (its bits in the state), or a rescan is
 * due (STATE_RESCAN), or the buffer holds, from `start`, nothing (and then start == end == 0 and
 * STATE_IN_SPAN and STATE_FLUSHING are clear) or one incomplete candidate, with d->checksum the
 * XOR of its bytes buffer[start..end) and STATE_FLUSHING clear. The bulk path relies on this. */

static void set_flag(ctrlbus_decoder_t *d, uint8_t flag)
{
    d->state = (uint8_t)(d->state | flag);
}

static void clear_flag(ctrlbus_decoder_t *d, uint8_t flag)
{
    d->state = (uint8_t)(d->state & (uint8_t)~flag);
}

/* The header size of a candidate: flag and length bytes. */
static uint32_t header_size(uint8_t flag)
{
    return flag == CTRLBUS_FLAG_STANDARD ? 2u : 3u;
}

/* The LEN field of a candidate whose header is at bytes[0..header). */
static uint32_t length_field(const uint8_t *bytes, uint32_t header)
{
    uint32_t len_field = bytes[1];
    if (header == 3u) {
        len_field |= (uint32_t)bytes[2] << 8;
    }
    return len_field;
}

/* Adds n to the counter of d->stats that belongs to rx: frames (CTRLBUS_RX_FRAME), bytes_discarded
 * (CTRLBUS_RX_GARBAGE), then checksum_errors, oversize, timeouts and empty_frames (the events, in
 * the order of ctrlbus_rx_t), and resyncs (COUNT_RESYNCS, after them). */
#define COUNT_RESYNCS 7u
typedef char stats_follow_rx_order[(offsetof(ctrlbus_decoder_stats_t, checksum_errors) ==
                                        (CTRLBUS_RX_CHECKSUM_ERROR - 1u) * sizeof(uint32_t) &&
                                    offsetof(ctrlbus_decoder_stats_t, empty_frames) ==
                                        (CTRLBUS_RX_EMPTY_FRAME - 1u) * sizeof(uint32_t) &&
                                    offsetof(ctrlbus_decoder_stats_t, resyncs) ==
                                        (COUNT_RESYNCS - 1u) * sizeof(uint32_t))
                                       ? 1
                                       : -1];

static void add_count(ctrlbus_decoder_t *d, unsigned rx, uint32_t n)
{
    if (d->stats != NULL) {
        *(uint32_t *)(void *)((char *)d->stats + (rx - 1u) * sizeof(uint32_t)) += n;
    }
}

#if CTRLBUS_DECODER_FAST
static void count(uint32_t *counter)
{
    *counter += 1u;
}
#endif

int32_t ctrlbus_decoder_init(ctrlbus_decoder_t *decoder, uint8_t *buffer, size_t buffer_size,
                             uint16_t timeout_ms, ctrlbus_decoder_stats_t *stats)
{
    if (decoder == NULL || buffer == NULL || buffer_size < CTRLBUS_DECODER_BUFFER_MIN) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    decoder->buffer = buffer;
    decoder->stats = stats;
#if SIZE_MAX > CTRLBUS_FRAME_MAX /* a 16-bit size_t cannot exceed it (AVR) */
    if (buffer_size > CTRLBUS_FRAME_MAX) {
        buffer_size = CTRLBUS_FRAME_MAX;
    }
#endif
    decoder->max_frame = (uint32_t)buffer_size;
    decoder->timeout_ms = timeout_ms;
    decoder->last_byte_ms = 0;
    if (stats != NULL) {
        /* Field by field, so that no memset is pulled in on an MCU (gcc makes one of a loop). */
        stats->frames = stats->bytes_discarded = stats->checksum_errors = stats->oversize = 0;
        stats->timeouts = stats->empty_frames = stats->resyncs = 0;
    }
    ctrlbus_decoder_reset(decoder);
    return CTRLBUS_OK;
}

void ctrlbus_decoder_reset(ctrlbus_decoder_t *decoder)
{
    if (decoder == NULL) {
        return;
    }
    decoder->start = 0;
    decoder->end = 0;
    decoder->complete_at = 0;
    decoder->checksum = 0;
    decoder->state = 0;
}

bool ctrlbus_decoder_busy(const ctrlbus_decoder_t *decoder)
{
    return decoder != NULL && (decoder->end > decoder->start || (decoder->state & STATE_HELD));
}

const char *ctrlbus_rx_name(ctrlbus_rx_t rx)
{
    switch (rx) {
    case CTRLBUS_RX_NONE: return "none";
    case CTRLBUS_RX_FRAME: return "frame";
    case CTRLBUS_RX_GARBAGE: return "garbage";
    case CTRLBUS_RX_CHECKSUM_ERROR: return "checksum_error";
    case CTRLBUS_RX_OVERSIZE: return "oversize";
    case CTRLBUS_RX_TIMEOUT: return "timeout";
    case CTRLBUS_RX_EMPTY_FRAME: return "empty_frame";
    case CTRLBUS_RX_BUSY: return "busy";
    default: return "unknown";
    }
}

/* Rule 5 would fail the partial candidate (if there is one) at now_ms. */
static bool timed_out(const ctrlbus_decoder_t *d, uint32_t now_ms)
{
    uint32_t elapsed = now_ms - d->last_byte_ms;
    return d->timeout_ms != 0 && elapsed > d->timeout_ms && elapsed < TIME_BACKWARDS;
}

/* Moves the partial candidate to the front of the buffer, to make room behind it. */
static void move_to_front(ctrlbus_decoder_t *d)
{
    uint32_t keep = d->end - d->start;
    for (uint32_t i = 0; i < keep; i++) { /* a plain loop: no libc needed on an MCU */
        d->buffer[i] = d->buffer[d->start + i];
    }
    d->start = 0;
    d->end = keep;
}

#if CTRLBUS_DECODER_FAST != 1
/* Fills in *frame (when not NULL) for the frame of `size` bytes at bytes[0..): the compact core's
 * one copy of this, for next() and (level 2) take_frame(). */
#if CTRLBUS_DECODER_FAST
RARE
#endif
static void describe_frame(ctrlbus_frame_t *frame, const uint8_t *bytes, uint32_t size)
{
    if (frame != NULL) {
        uint32_t header = header_size(bytes[0]);
        frame->is_long = header == 3u;
        frame->cmd = bytes[header];
        frame->payload = bytes + header + 1u;
        frame->payload_len = (size_t)(size - header - 2u);
    }
}
#endif

#if CTRLBUS_DECODER_FAST
/* ctrlbus_decoder_take() hands out the frame whose bytes are at bytes[0..): its header and LEN are
 * known. Nothing stays buffered; what the scan would leave behind is settled here (rules 2-3 and
 * the buffer running empty). Level 2's callers pass the frame's size instead and stamp the time
 * themselves: four arguments, all in registers on a small MCU.
 * TAKE_FRAME() is the call in the code both levels share. */
#if CTRLBUS_DECODER_FAST == 1
#define TAKE_FRAME(d, bytes, header, len_field, size, now_ms, frame)                              \
    take_frame(d, bytes, header, len_field, now_ms, frame)
IN_LINE static ctrlbus_rx_t take_frame(ctrlbus_decoder_t *d, const uint8_t *bytes, uint32_t header,
                                       uint32_t len_field, uint32_t now_ms, ctrlbus_frame_t *frame)
#else
#define TAKE_FRAME(d, bytes, header, len_field, size, now_ms, frame)                              \
    ((d)->last_byte_ms = (now_ms), take_frame(d, bytes, size, frame))
RARE /* one copy, for push_slow() and take_slow() */
static ctrlbus_rx_t take_frame(ctrlbus_decoder_t *d, const uint8_t *bytes, uint32_t size,
                               ctrlbus_frame_t *frame)
#endif
{
#if CTRLBUS_DECODER_FAST == 1
    if (frame != NULL) {
        frame->is_long = header == 3u;
        frame->cmd = bytes[header];
        frame->payload = bytes + header + 1u;
        frame->payload_len = (size_t)(len_field - 1u);
    }
#else
    describe_frame(frame, bytes, size);
#endif
    if (d->stats != NULL) {
        count(&d->stats->frames);
    }
    d->start = d->end = d->complete_at = 0;
    d->checksum = 0;
    clear_flag(d, STATE_EVENT_SINCE_FRAME | STATE_FLUSHING | STATE_IN_SPAN);
#if CTRLBUS_DECODER_FAST == 1
    d->last_byte_ms = now_ms;
#endif
    return CTRLBUS_RX_FRAME;
}
#endif

#if CTRLBUS_DECODER_FAST == 1
/* ---- level 1: the byte path, with the state the bulk path keeps ---------------------------- */

/* Records an event (rule 1's "an event was raised since the last frame") and returns it. */
static ctrlbus_rx_t raise_event(ctrlbus_decoder_t *d, ctrlbus_rx_t event)
{
    set_flag(d, STATE_EVENT_SINCE_FRAME);
    return event;
}

/* Rules 2-3: the complete candidate at `start` is a frame with a command. It stays at `start`;
 * ctrlbus_decoder_next() steps over it when it hands it out. */
static ctrlbus_rx_t yield_frame(ctrlbus_decoder_t *d)
{
    if (d->stats != NULL) {
        count(&d->stats->frames);
    }
    clear_flag(d, STATE_EVENT_SINCE_FRAME);
    return CTRLBUS_RX_FRAME;
}

/* Rule 4: the candidate at `start` failed. Counts it, drops its flag byte and makes everything
 * still buffered its span. Returns true when the failure is outermost, so its event is raised. */
static bool fail_candidate(ctrlbus_decoder_t *d, ctrlbus_rx_t kind)
{
    bool outermost = !(d->state & STATE_IN_SPAN);
    add_count(d, kind, 1u);
    add_count(d, COUNT_RESYNCS, 1u);
    add_count(d, CTRLBUS_RX_GARBAGE, 1u);
    d->start++;
    d->checksum = 0;
    set_flag(d, STATE_IN_SPAN);
    return outermost;
}

/* Drops n bytes at `start` that are not part of a yielded frame (rule 1 hunting, rule 2 empty
 * frame). Returns whether they lay in a failed candidate's span. */
static bool discard(ctrlbus_decoder_t *d, uint32_t n)
{
    bool in_span = (d->state & STATE_IN_SPAN) != 0;
    d->start += n;
    d->checksum = 0;
    if (d->stats != NULL) {
        d->stats->bytes_discarded += n;
    }
    return in_span;
}

/* The buffer has run empty: restart at its front, which keeps later frames contiguous, and leave
 * any failed candidate's span (nothing buffered can be in it any more). */
static void settle_empty(ctrlbus_decoder_t *d)
{
    if (d->state & STATE_HELD) {
        d->buffer[0] = d->buffer[d->end]; /* the held byte stays right behind the buffered ones */
    }
    d->start = d->end = 0;
    d->checksum = 0;
    clear_flag(d, STATE_FLUSHING | STATE_IN_SPAN);
}

/* The general path, one buffered byte at a time: scans from offset `pos`, where d->checksum is the
 * XOR of buffer[start..pos), until a result is found (returned, not yet recorded as pending) or
 * more bytes are needed (CTRLBUS_RX_NONE, with d->checksum covering buffer[start..end)). */
static ctrlbus_rx_t scan(ctrlbus_decoder_t *d, uint32_t pos)
{
    const uint8_t *buf = d->buffer;
    for (;; pos = d->start) {
        uint32_t avail = d->end - d->start;
        if (avail == 0) {
            settle_empty(d);
            return CTRLBUS_RX_NONE;
        }
        uint8_t flag = buf[d->start];
        if (flag != CTRLBUS_FLAG_STANDARD && flag != CTRLBUS_FLAG_LONG) {
            /* Rule 1: hunting. One garbage event per gap, none inside a span. */
            if (!discard(d, 1) && !(d->state & STATE_EVENT_SINCE_FRAME)) {
                return raise_event(d, CTRLBUS_RX_GARBAGE);
            }
            continue;
        }
        /* Rules 2 and 3: a candidate. Its size is known once its header is buffered. */
        uint32_t header = header_size(flag);
        ctrlbus_rx_t failure = CTRLBUS_RX_NONE;
        if (avail >= header) {
            uint32_t len_field = length_field(buf + d->start, header);
            uint32_t size = header + len_field + 1u;
            if (size > d->max_frame) {
                failure = CTRLBUS_RX_OVERSIZE;
            } else if (avail >= size) {
                uint32_t last = d->start + size - 1u;
                if (xor_bytes(d->checksum, buf + pos, (size_t)(last - pos)) != buf[last]) {
                    failure = CTRLBUS_RX_CHECKSUM_ERROR;
                } else if (len_field == 0) {
                    /* LEN = 0: well-formed but without a command; its bytes are discarded. */
                    if (d->stats != NULL) {
                        count(&d->stats->empty_frames);
                    }
                    if (!discard(d, size)) {
                        return raise_event(d, CTRLBUS_RX_EMPTY_FRAME);
                    }
                    continue;
                } else {
                    return yield_frame(d);
                }
            }
        }
        if (failure == CTRLBUS_RX_NONE) {
            if (!(d->state & STATE_FLUSHING)) {
                /* Incomplete: remember the checksum so far and wait for more bytes. */
                d->checksum = xor_bytes(d->checksum, buf + pos, (size_t)(d->end - pos));
                return CTRLBUS_RX_NONE;
            }
            failure = CTRLBUS_RX_TIMEOUT; /* rule 5: a stale partial frame */
        }
        if (fail_candidate(d, failure)) {
            return raise_event(d, failure);
        }
    }
}

/* Records a result found by scan() as pending until ctrlbus_decoder_next() takes it. */
static bool hold(ctrlbus_decoder_t *d, ctrlbus_rx_t rx)
{
    if (rx == CTRLBUS_RX_NONE) {
        return false;
    }
    d->state = (uint8_t)((d->state & (uint8_t)~STATE_PENDING_MASK) | (uint8_t)rx);
    return true;
}

/* Finishes a rescan that a taken result interrupted, then takes a held byte (see STATE_HELD).
 * Returns the first result found (or NONE). */
static ctrlbus_rx_t resume(ctrlbus_decoder_t *d)
{
    if (d->state & STATE_RESCAN) {
        clear_flag(d, STATE_RESCAN);
        d->checksum = 0;
        ctrlbus_rx_t rx = scan(d, d->start);
        if (rx != CTRLBUS_RX_NONE) {
            return rx;
        }
    }
    if (!(d->state & STATE_HELD)) {
        return CTRLBUS_RX_NONE;
    }
    /* d->checksum covers buffer[start..end) (scan() left it so), and the byte is at buffer[end]. */
    clear_flag(d, STATE_HELD);
    d->end++;
    return scan(d, d->end - 1u);
}

/* Rule 5, checked before new bytes are taken. Returns a result to hold, or NONE. */
static ctrlbus_rx_t apply_timeout(ctrlbus_decoder_t *d, uint32_t now_ms)
{
    if (d->end == d->start || !timed_out(d, now_ms)) {
        return CTRLBUS_RX_NONE;
    }
    d->complete_at = 0;
    set_flag(d, STATE_FLUSHING);
    d->checksum = 0; /* the XOR of buffer[start..start) for the scan below */
    /* The waiting candidate at `start` is incomplete, so the scan fails it as a timeout first;
     * the stale bytes after it are rescanned (the same scan, or after its event is taken). */
    return scan(d, d->start);
}

#if CTRLBUS_DECODER_FAST
/* ---- the bulk path: the same rules, many bytes per step ------------------------------------- */

/* Appends n bytes to the buffer at dst and returns checksum XOR all of them. A machine word at a
 * time: each word goes through memcpy, which compilers turn into plain loads and stores that are
 * safe at any alignment; the tail is taken in halves (4, 2, 1 bytes). */
IN_LINE static uint8_t copy_xor(uint8_t *dst, const uint8_t *src, size_t n, uint8_t checksum)
{
#if !CTRLBUS_WORD_READS_
    /* Without unaligned loads (Cortex-M0) each memcpy below is a call: bytes are cheaper. */
    for (; n != 0; n--) {
        *dst++ = *src;
        checksum ^= *src++;
    }
    return checksum;
#else
    if (n >= 2u) {
        size_t acc = 0; /* the XOR of the bytes taken, lane by lane */
        while (n >= sizeof acc) {
            size_t word;
            memcpy(&word, src, sizeof word);
            memcpy(dst, &word, sizeof word);
            acc ^= word;
            src += sizeof word;
            dst += sizeof word;
            n -= sizeof word;
        }
        if (sizeof acc > 4u && n >= 4u) {
            uint32_t word;
            memcpy(&word, src, 4u);
            memcpy(dst, &word, 4u);
            acc ^= (size_t)word; /* only compiled in with a 64-bit size_t */
            src += 4;
            dst += 4;
            n -= 4u;
        }
        if (n >= 2u) {
            uint16_t word;
            memcpy(&word, src, 2u);
            memcpy(dst, &word, 2u);
            acc ^= word;
            src += 2;
            dst += 2;
            n -= 2u;
        }
        for (unsigned shift = (unsigned)sizeof acc * 4u; shift >= 8u; shift /= 2u) {
            acc ^= acc >> shift; /* fold: the low byte becomes the XOR of all the lanes */
        }
        checksum = (uint8_t)(checksum ^ (acc & 0xFFu));
    }
    if (n != 0) {
        *dst = *src;
        checksum ^= *src;
    }
    return checksum;
#endif
}

/* take_bulk()'s word for "complete, but not a frame with a command: scan() settles it". */
#define RX_SETTLE_BY_SCAN ((ctrlbus_rx_t)0xFF)

/* Takes as many of the n (> 0) input bytes at `in` as it can in one step and returns how many, or
 * 0 when the byte at `in` needs the general path (a header split between feeds, an oversize
 * candidate). For a decoder with no result pending, no rescan due and no timeout to apply. Its
 * result goes to *rx: NONE, GARBAGE, FRAME or RX_SETTLE_BY_SCAN. It leaves exactly the state that
 * feeding the same bytes one at a time through scan() leaves:
 * - over an empty buffer, the bytes before the next flag are discarded (rule 1);
 * - a candidate whose size is known (from the buffer, or from the input when nothing is buffered)
 *   takes the bytes it still needs, as many as are here. When that completes it, the XOR of all
 *   its bytes is 0 exactly when its checksum is right, and the common outcome (a frame with a
 *   command) is settled here. */
IN_LINE static size_t take_bulk(ctrlbus_decoder_t *d, const uint8_t *in, size_t n, ctrlbus_rx_t *rx)
{
    uint32_t have = d->end - d->start;
    const uint8_t *cand = in;
    *rx = CTRLBUS_RX_NONE;
    if (have != 0) {
        cand = d->buffer + d->start;
    } else if ((in[0] | 0x40u) != CTRLBUS_FLAG_LONG) { /* neither 0x10 nor 0x50 */
        size_t skip = 1;
        while (skip < n && (in[skip] | 0x40u) != CTRLBUS_FLAG_LONG) {
            skip++;
        }
        if (!(d->state & (STATE_EVENT_SINCE_FRAME | STATE_IN_SPAN))) {
            skip = 1; /* the byte that raises the event ends this feed */
            *rx = raise_event(d, CTRLBUS_RX_GARBAGE);
        }
        if (d->stats != NULL) {
            d->stats->bytes_discarded += (uint32_t)skip;
        }
        settle_empty(d);
        return skip;
    }
    uint32_t header = header_size(cand[0]);
    if ((have != 0 ? have : n) < header) {
        return 0;
    }
    uint32_t len_field = length_field(cand, header);
    uint32_t size = header + len_field + 1u;
    if (size > d->max_frame || size <= have) {
        return 0; /* oversize, or (never: scan() settles it) a complete candidate */
    }
    uint32_t need = size - have;
    uint32_t take = need <= n ? need : (uint32_t)n;
    if (d->end + take > d->max_frame) {
        move_to_front(d); /* the candidate fits the buffer, so start > 0 here */
    }
    d->checksum = copy_xor(d->buffer + d->end, in, (size_t)take, d->checksum);
    d->end += take;
    if (take == need) {
        *rx = d->checksum == 0 && len_field != 0 ? yield_frame(d) : RX_SETTLE_BY_SCAN;
    }
    return (size_t)take; /* at most n */
}

/* For RX_SETTLE_BY_SCAN: scan() settles the complete candidate (a checksum failure with its
 * backtracking, or an empty frame), resumed at its last byte. */
static ctrlbus_rx_t settle_by_scan(ctrlbus_decoder_t *d)
{
    uint32_t last = d->end - 1u;
    d->checksum ^= d->buffer[last]; /* scan() wants the XOR of the bytes before `last` */
    return scan(d, last);
}
#endif

/* ctrlbus_decoder_feed() for a usable decoder: the general path. */
OUT_OF_LINE static size_t feed_bytes(ctrlbus_decoder_t *d, const uint8_t *data, size_t len,
                                     uint32_t now_ms)
{
    if ((d->state & STATE_PENDING_MASK) != 0 || hold(d, resume(d)) ||
        hold(d, apply_timeout(d, now_ms))) {
        return 0;
    }
    if (data == NULL || len == 0) {
        return len; /* no bytes: report them all taken so a caller's loop ends */
    }
    d->last_byte_ms = now_ms; /* at least one byte is taken below */
    for (size_t used = 0; used < len;) {
#if CTRLBUS_DECODER_FAST
        ctrlbus_rx_t rx;
        size_t taken = take_bulk(d, data + used, len - used, &rx);
        if (taken > 0) {
            used += taken;
            if (hold(d, rx == RX_SETTLE_BY_SCAN ? settle_by_scan(d) : rx)) {
                return used;
            }
            continue;
        }
#endif
        if (d->end == d->max_frame) {
            /* Full: move the partial candidate to the front. While waiting, it is shorter than
             * max_frame (it would have completed or failed otherwise), so start > 0 here. */
            move_to_front(d);
        }
        d->buffer[d->end++] = data[used++];
        if (hold(d, scan(d, d->end - 1u))) {
            return used;
        }
    }
    return len;
}

#if DECODER_SHORTCUTS
/* ctrlbus_decoder_feed() for a usable decoder with no result pending, no rescan due and some bytes:
 * one take_bulk() step, then the general path for whatever remains. */
OUT_OF_LINE static size_t feed_bulk(ctrlbus_decoder_t *d, const uint8_t *data, size_t len,
                                    uint32_t now_ms)
{
    if (d->end != d->start && timed_out(d, now_ms)) {
        return feed_bytes(d, data, len, now_ms);
    }
    ctrlbus_rx_t rx;
    size_t taken = take_bulk(d, data, len, &rx);
    if (taken == 0) {
        return feed_bytes(d, data, len, now_ms);
    }
    d->last_byte_ms = now_ms;
    if (rx == RX_SETTLE_BY_SCAN) {
        rx = settle_by_scan(d);
    }
    if (hold(d, rx) || taken == len) {
        return taken;
    }
    return taken + feed_bytes(d, data + taken, len - taken, now_ms);
}
#endif

#if DECODER_SHORTCUTS
/* A feed of one byte (a UART interrupt's), in the cases that need none of take_bulk()'s rarer
 * steps: it starts a candidate in an empty buffer, extends one (its header not yet complete, or
 * complete with an acceptable size), or completes one as a frame with a command. Returns false,
 * having changed nothing, when the byte needs the general path: garbage, a timeout to apply, a full
 * buffer, an oversize length, a failed or empty candidate. For a decoder with no result pending and
 * no rescan due. */
IN_LINE static bool take_one(ctrlbus_decoder_t *d, uint8_t byte, uint32_t now_ms)
{
    uint32_t have = d->end - d->start;
    if (have == 0) {
        if ((byte | 0x40u) != CTRLBUS_FLAG_LONG) {
            return false;
        }
    } else {
        if (d->end == d->max_frame || timed_out(d, now_ms)) {
            return false;
        }
        const uint8_t *cand = d->buffer + d->start;
        uint32_t header = header_size(cand[0]);
        if (have + 1u >= header) {
            uint32_t len_field = have + 1u == header
                                     ? (header == 2u ? byte : cand[1] | (uint32_t)byte << 8)
                                     : length_field(cand, header);
            uint32_t size = header + len_field + 1u;
            if (size > d->max_frame) {
                return false;
            }
            if (have + 1u == size) {
                if ((d->checksum ^ byte) != 0 || len_field == 0) {
                    return false;
                }
                d->buffer[d->end++] = byte;
                d->checksum = 0;
                d->last_byte_ms = now_ms;
                hold(d, yield_frame(d));
                return true;
            }
        }
    }
    d->buffer[d->end++] = byte;
    d->checksum ^= byte;
    d->last_byte_ms = now_ms;
    return true;
}
#endif

size_t ctrlbus_decoder_feed(ctrlbus_decoder_t *decoder, const uint8_t *data, size_t len,
                            uint32_t now_ms)
{
    ctrlbus_decoder_t *d = decoder;
    if (d == NULL || d->buffer == NULL) {
        return len; /* nowhere to put them: report them taken so a caller's loop ends */
    }
    if (data != NULL && len != 0) {
        d->complete_at = 0; /* push()'s inline path waits until push_slow() has looked again */
    }
#if DECODER_SHORTCUTS
    if (data != NULL && len != 0 && (d->state & STATE_WAITING) == 0) {
        /* The most common cases, settled right here: nothing buffered, and the input starts with
         * a whole valid frame with a command, or with the start of a frame that goes on beyond
         * it. This is take_bulk() cut down to those cases (start is 0, the buffer being empty); a
         * candidate that turns out otherwise is taken again by feed_bulk(). */
        if (d->end == d->start && len >= CTRLBUS_STANDARD_OVERHEAD &&
            (data[0] | 0x40u) == CTRLBUS_FLAG_LONG) {
            uint32_t header = header_size(data[0]);
            uint32_t len_field = length_field(data, header);
            uint32_t size = header + len_field + 1u;
            if (size > len && size <= d->max_frame) {
                d->checksum = copy_xor(d->buffer, data, len, 0);
                d->end = (uint32_t)len;
                d->last_byte_ms = now_ms;
                return len;
            }
            if (len_field != 0 && size <= len && size <= d->max_frame &&
                copy_xor(d->buffer, data, (size_t)size, 0) == 0) {
                d->end = size;
                d->last_byte_ms = now_ms;
                hold(d, yield_frame(d));
                return (size_t)size; /* at most len */
            }
        }
        if (len == 1u && take_one(d, data[0], now_ms)) {
            return 1;
        }
        return feed_bulk(d, data, len, now_ms);
    }
#endif
    return feed_bytes(d, data, len, now_ms);
}

void ctrlbus_decoder_tick(ctrlbus_decoder_t *decoder, uint32_t now_ms)
{
    (void)ctrlbus_decoder_feed(decoder, NULL, 0u, now_ms); /* a feed of no bytes */
}

/* Hands out the pending result rx (already cleared from the state). */
IN_LINE static ctrlbus_rx_t hand_out(ctrlbus_decoder_t *d, ctrlbus_frame_t *frame, ctrlbus_rx_t rx)
{
    if (rx == CTRLBUS_RX_FRAME) {
        const uint8_t *bytes = d->buffer + d->start;
        uint32_t header = header_size(bytes[0]);
        uint32_t len_field = length_field(bytes, header);
        if (frame != NULL) {
            frame->is_long = header == 3u;
            frame->cmd = bytes[header];
            frame->payload = bytes + header + 1u;
            frame->payload_len = (size_t)(len_field - 1u);
        }
        d->start += header + len_field + 1u;
    }
    /* Scanning resumes at `start` at the next call. With the bulk path, when nothing is left
     * buffered, the buffer is settled now instead (as that scan would), which keeps the next call
     * cheap; the frame's bytes stay where they are until then. */
#if CTRLBUS_DECODER_FAST
    if (d->start == d->end) {
        settle_empty(d);
        return rx;
    }
#endif
    set_flag(d, STATE_RESCAN);
    return rx;
}

#if DECODER_SHORTCUTS
/* ctrlbus_decoder_next() when nothing is pending but a rescan is due: out of line, so that handing
 * out a pending result saves no registers. (Without the bulk path, one call of hand_out() is
 * smaller.) */
OUT_OF_LINE static ctrlbus_rx_t next_after_rescan(ctrlbus_decoder_t *d, ctrlbus_frame_t *frame)
{
    ctrlbus_rx_t rx = resume(d);
    return rx == CTRLBUS_RX_NONE ? rx : hand_out(d, frame, rx);
}
#endif

ctrlbus_rx_t ctrlbus_decoder_next(ctrlbus_decoder_t *decoder, ctrlbus_frame_t *frame)
{
    ctrlbus_decoder_t *d = decoder;
    if (d == NULL || d->buffer == NULL) {
        return CTRLBUS_RX_NONE;
    }
    ctrlbus_rx_t rx = (ctrlbus_rx_t)(d->state & STATE_PENDING_MASK);
#if DECODER_SHORTCUTS
    if (rx != CTRLBUS_RX_NONE) {
        clear_flag(d, STATE_PENDING_MASK);
        return hand_out(d, frame, rx);
    }
    return (d->state & (STATE_RESCAN | STATE_HELD)) ? next_after_rescan(d, frame) : CTRLBUS_RX_NONE;
#else
    if (rx != CTRLBUS_RX_NONE) {
        clear_flag(d, STATE_PENDING_MASK);
    } else if (!(d->state & (STATE_RESCAN | STATE_HELD)) || (rx = resume(d)) == CTRLBUS_RX_NONE) {
        return CTRLBUS_RX_NONE;
    }
    return hand_out(d, frame, rx);
#endif
}

#else /* CTRLBUS_DECODER_FAST 0 or 2 */
/* ---- levels 0 and 2: the compact core -------------------------------------------------------
 *
 * The same rules and the same state bits, in less code (level 0 is this alone, the smallest
 * decoder; level 2 adds the few steps that make it fast at -Os: push()'s inline path through an
 * armed candidate, feed() copying a candidate's known remainder in one run, take() checking a
 * whole frame in place). The scan advances `start` over the bytes it drops (and next() over a
 * frame it hands out); a scan that ends waiting for more bytes moves its incomplete candidate to
 * the front of the buffer, where new bytes have room behind it (a waiting candidate is shorter
 * than max_frame, so the byte after it always fits). A candidate's checksum is the XOR of its
 * bytes, taken once when it is complete. d->complete_at holds the size of the frame found (for
 * next()) or, after a scan that found nothing, of the incomplete candidate at the front when its
 * header is buffered (0 otherwise, and after next() hands out a frame at level 2): push()'s inline
 * path and feed()'s runs append up to it without a scan. d->checksum holds the byte that
 * STATE_HELD keeps. Between calls only an incomplete candidate (or nothing) is buffered, so a scan
 * that finds nothing new costs O(1), and every call can simply scan first (level 2's next() skips
 * even that when nothing is left to resume). A result found is held in the state until next()
 * hands it out; after that STATE_RESCAN says that more may wait in the buffered bytes. */

/* Rules 1, 2 and 4: drops `drop` bytes at `start` that are not part of a yielded frame, as rx:
 * CTRLBUS_RX_GARBAGE (a byte while hunting), CTRLBUS_RX_EMPTY_FRAME, or a failure (its flag byte).
 * Returns rx when it raises its event, else CTRLBUS_RX_NONE. */
RARE static ctrlbus_rx_t discard(ctrlbus_decoder_t *d, unsigned rx, uint32_t drop)
{
    unsigned quiet = d->state & STATE_IN_SPAN; /* rule 4: an echo of a fault already reported */
    ctrlbus_decoder_stats_t *stats = d->stats;
    if (stats != NULL) {
        stats->bytes_discarded += drop;
    }
    if (rx == CTRLBUS_RX_GARBAGE) {
        quiet |= d->state & STATE_EVENT_SINCE_FRAME; /* rule 1: one event per gap */
    } else {
        add_count(d, rx, 1u);
        if (rx != CTRLBUS_RX_EMPTY_FRAME) {
            /* a failure: everything buffered after its flag is its span */
            if (stats != NULL) {
                stats->resyncs += 1u;
            }
            set_flag(d, STATE_IN_SPAN);
        }
    }
    d->start += drop;
    if (quiet) {
        return CTRLBUS_RX_NONE;
    }
    set_flag(d, STATE_EVENT_SINCE_FRAME);
    return (ctrlbus_rx_t)rx;
}

/* The XOR of a complete candidate's bytes (0 for a right checksum): a word at a time at level 2. */
static uint8_t candidate_xor(const uint8_t *cand, uint32_t size)
{
#if CTRLBUS_DECODER_FAST
    return ctrlbus_xor_in_place_(cand, size);
#else
    return xor_bytes(0u, cand, (size_t)size);
#endif
}

/* Rules 1-5 over the buffered bytes, from `start`: finds the first result (a frame stays at
 * `start` for next() to hand out) and records it as waiting for next(), or none when more bytes
 * are needed; a rescan is no longer due. Returns it (CTRLBUS_RX_NONE: none; not a bool, which
 * would cost a conversion). */
static unsigned scan(ctrlbus_decoder_t *d)
{
    ctrlbus_rx_t found;
    uint32_t size;
    for (;;) {
        uint32_t avail = d->end - d->start;
        const uint8_t *cand = d->buffer + d->start;
        unsigned rx = CTRLBUS_RX_GARBAGE;
        uint32_t drop = 1u;
        size = 0u;
        if (avail == 0u) {
            /* Run empty: leave any span (nothing buffered is in it any more). A byte held behind
             * the stale bytes of a timeout goes in now. */
            unsigned held = d->state & STATE_HELD;
            d->buffer[0] = d->checksum;
            d->start = 0u;
            d->end = held ? 1u : 0u;
            clear_flag(d, STATE_FLUSHING | STATE_IN_SPAN | STATE_HELD);
            if (held) {
                continue;
            }
            found = CTRLBUS_RX_NONE;
            break;
        }
        if ((cand[0] | 0x40u) == CTRLBUS_FLAG_LONG) {
            /* Rules 2-3: a candidate; its size is known once its header is buffered. */
            uint32_t header = header_size(cand[0]);
            uint32_t len_field = 0u;
            if (avail >= header) {
                len_field = length_field(cand, header);
                size = header + len_field + 1u;
            }
            if (size > d->max_frame) {
                rx = CTRLBUS_RX_OVERSIZE;
            } else if (size != 0u && avail >= size) {
                if (candidate_xor(cand, size) != 0u) {
                    rx = CTRLBUS_RX_CHECKSUM_ERROR;
                } else if (len_field != 0u) {
                    add_count(d, CTRLBUS_RX_FRAME, 1u);
                    clear_flag(d, STATE_EVENT_SINCE_FRAME);
                    found = CTRLBUS_RX_FRAME;
                    break;
                } else {
                    rx = CTRLBUS_RX_EMPTY_FRAME; /* well-formed, no command: all discarded */
                    drop = size;
                }
            } else if (d->state & STATE_FLUSHING) {
                rx = CTRLBUS_RX_TIMEOUT; /* rule 5: a stale partial frame */
            } else {
                /* Incomplete: wait for more bytes, at the front, where they have room. */
                if (d->start != 0u) {
                    move_to_front(d);
                }
                found = CTRLBUS_RX_NONE;
                break;
            }
        }
        size = 0u;
        found = discard(d, rx, drop);
        if (found != CTRLBUS_RX_NONE) {
            break;
        }
    }
    d->complete_at = size;
    d->state =
        (uint8_t)((d->state & (uint8_t)~(STATE_PENDING_MASK | STATE_RESCAN)) | (uint8_t)found);
    return found;
}

/* What every call that takes bytes does first: the results the buffered bytes still hold, then
 * rule 5 at now_ms (the candidate at the front fails, and the bytes after it are rescanned as
 * stale). Returns nonzero when a result waits. */
static unsigned results_first(ctrlbus_decoder_t *d, uint32_t now_ms)
{
    if (d->state & STATE_PENDING_MASK) {
        return true;
    }
    if (d->end != d->start && timed_out(d, now_ms)) {
        set_flag(d, STATE_FLUSHING);
    }
#if CTRLBUS_DECODER_FAST
    else if (d->start == 0u && !(d->state & STATE_WAITING)) {
        /* Nothing waits and what is buffered is at the front (not behind a result handed out):
         * an incomplete candidate, or nothing, on which a scan would change nothing. */
        return false;
    }
#endif
    return scan(d);
}

#if CTRLBUS_DECODER_FAST
/* Appends n (> 0) bytes behind the buffered ones (a plain loop: no libc needed on an MCU). */
static void append(ctrlbus_decoder_t *d, const uint8_t *bytes, size_t n)
{
    uint8_t *dst = d->buffer + d->end;
    d->end += (uint32_t)n;
    for (size_t i = 0; i < n; i++) {
        dst[i] = bytes[i];
    }
}
#endif

size_t ctrlbus_decoder_feed(ctrlbus_decoder_t *decoder, const uint8_t *data, size_t len,
                            uint32_t now_ms)
{
    ctrlbus_decoder_t *d = decoder;
    if (d == NULL || d->buffer == NULL) {
        return len; /* nowhere to put them: report them taken so a caller's loop ends */
    }
    if (results_first(d, now_ms)) {
        return 0;
    }
    if (data == NULL || len == 0u) {
        return len; /* no bytes: report them all taken so a caller's loop ends */
    }
    d->last_byte_ms = now_ms;
    for (size_t used = 0; used < len;) {
#if CTRLBUS_DECODER_FAST
        /* When the candidate's size is known, the bytes that do not complete it change nothing
         * that a scan looks at: they go in as one run, scanned once. */
        size_t run = 1u;
        if (d->complete_at > d->end) {
            run = (size_t)(d->complete_at - d->end); /* at most max_frame, which fits a size_t */
            if (run > len - used) {
                run = len - used;
            }
        }
        append(d, data + used, run);
        used += run;
#else
        d->buffer[d->end++] = data[used++]; /* behind a waiting candidate (at the front) */
#endif
        if (scan(d)) {
            return used;
        }
    }
    return len;
}

/* (Not a feed of no bytes, so that a base linking push, next and tick leaves feed out.) */
void ctrlbus_decoder_tick(ctrlbus_decoder_t *decoder, uint32_t now_ms)
{
    if (decoder != NULL && decoder->buffer != NULL) {
        (void)results_first(decoder, now_ms);
    }
}

ctrlbus_rx_t ctrlbus_decoder_next(ctrlbus_decoder_t *decoder, ctrlbus_frame_t *frame)
{
    ctrlbus_decoder_t *d = decoder;
    if (d == NULL || d->buffer == NULL) {
        return CTRLBUS_RX_NONE;
    }
    if ((d->state & STATE_PENDING_MASK) == 0u) {
#if CTRLBUS_DECODER_FAST
        /* Nothing to resume: every call that takes bytes at level 2 has settled them as a scan
         * would (level 0's push_slow() leaves its byte to this scan). */
        if (!(d->state & (STATE_RESCAN | STATE_HELD))) {
            return CTRLBUS_RX_NONE;
        }
#endif
        (void)scan(d);
    }
    ctrlbus_rx_t rx = (ctrlbus_rx_t)(d->state & STATE_PENDING_MASK);
    clear_flag(d, STATE_PENDING_MASK);
    if (rx == CTRLBUS_RX_FRAME) {
        /* The frame lies at `start`; scanning resumes after it at the next call. */
        uint32_t size = d->complete_at;
        describe_frame(frame, d->buffer + d->start, size);
        d->start += size;
#if CTRLBUS_DECODER_FAST
        d->complete_at = 0u; /* push()'s inline path waits for a scan (level 0 has none) */
#endif
    }
    if (rx != CTRLBUS_RX_NONE && (d->start != d->end || (d->state & STATE_HELD))) {
        set_flag(d, STATE_RESCAN); /* more results may wait in the bytes still buffered */
    }
    return rx;
}

ctrlbus_rx_t ctrlbus_decoder_push_slow(ctrlbus_decoder_t *decoder, uint8_t byte, uint32_t now_ms,
                                       ctrlbus_frame_t *frame)
{
    ctrlbus_decoder_t *d = decoder;
    if (d == NULL || d->buffer == NULL) {
        return CTRLBUS_RX_NONE;
    }
    if (d->state & STATE_WAITING) {
        return CTRLBUS_RX_BUSY;
    }
#if CTRLBUS_DECODER_FAST
    /* The common bytes, when the candidate is at the front (or nothing is buffered) and no timeout
     * applies, each settled as the scan would settle it: a flag into the empty buffer, the rest of
     * a header (whose last byte arms the candidate with its size, when that fits), a byte inside
     * an armed candidate at a new millisecond (push()'s inline path takes the others), and the
     * last byte when it completes a frame with a command. The byte goes to buffer[end] first; the
     * general path below puts it there again. */
    uint32_t end = d->end;
    uint8_t *cand = d->buffer;
    if (d->start == 0u && (end == 0u || now_ms == d->last_byte_ms || !timed_out(d, now_ms))) {
        uint32_t complete_at = d->complete_at;
        cand[end] = byte;
        if (end == 0u) {
            if ((byte | 0x40u) != CTRLBUS_FLAG_LONG) {
                goto general; /* garbage */
            }
        } else if (complete_at == 0u) {
            uint32_t header = header_size(cand[0]);
            if (end + 1u == header) {
                complete_at = header + length_field(cand, header) + 1u;
                if (complete_at > d->max_frame) {
                    goto general; /* oversize */
                }
                d->complete_at = complete_at;
            }
        } else if (end + 1u == complete_at) {
            if (complete_at == header_size(cand[0]) + 1u || candidate_xor(cand, complete_at) != 0u) {
                goto general; /* an empty frame (LEN 0), or a checksum error */
            }
            d->last_byte_ms = now_ms;
            return take_frame(d, cand, complete_at, frame);
        }
        d->end = end + 1u;
        d->last_byte_ms = now_ms;
        return CTRLBUS_RX_NONE;
    }
general:
#endif
    if (results_first(d, now_ms)) {
        /* A timeout applied before the byte, and its results come first: the byte waits behind
         * the stale bytes (see STATE_HELD) and goes in when they are used up. */
        d->checksum = byte;
        set_flag(d, STATE_HELD);
    } else {
        d->buffer[d->end++] = byte; /* as a feed of one byte; next() scans it */
#if CTRLBUS_DECODER_FAST
        d->last_byte_ms = now_ms;
        if (!scan(d)) {
            return CTRLBUS_RX_NONE; /* (next() would scan again, to find the same) */
        }
#endif
    }
    d->last_byte_ms = now_ms;
    return ctrlbus_decoder_next(d, frame);
}
#endif /* the two cores */

/* ---- take: results straight from the caller's bytes ----------------------------------------- */

/* ctrlbus_decoder_take() in general: results first, then feeds, as its contract spells out. */
OUT_OF_LINE static ctrlbus_rx_t take_general(ctrlbus_decoder_t *d, const uint8_t **data,
                                             size_t *len, uint32_t now_ms, ctrlbus_frame_t *frame)
{
    if (*data == NULL) {
        *len = 0; /* nothing to read: as feed(), report the bytes taken */
    }
    for (;;) {
        ctrlbus_rx_t rx = ctrlbus_decoder_next(d, frame);
        if (rx != CTRLBUS_RX_NONE || *len == 0) {
            return rx;
        }
        size_t used = ctrlbus_decoder_feed(d, *data, *len, now_ms);
        *data += used;
        *len -= used;
        if (used == 0 && !(d->state & STATE_WAITING)) {
            return CTRLBUS_RX_NONE; /* cannot happen with a usable decoder; no spinning if it did */
        }
    }
}

ctrlbus_rx_t ctrlbus_decoder_take_slow(ctrlbus_decoder_t *decoder, const uint8_t **data,
                                       size_t *len, uint32_t now_ms, ctrlbus_frame_t *frame)
{
    ctrlbus_decoder_t *d = decoder;
    if (d == NULL || data == NULL || len == NULL) {
        return CTRLBUS_RX_NONE;
    }
#if CTRLBUS_DECODER_FAST
    /* The common cases when nothing waits (so next() has nothing to hand out), each settled as the
     * feed and next() calls would settle it; anything else takes the general path. */
    const uint8_t *in = *data;
    size_t n = *len;
    /* (A decoder never initialised has no buffer and max_frame 0: only the garbage step below
     * could take it for a usable one, and checks.) */
    if (!(d->state & STATE_WAITING) && in != NULL) {
        if (n == 0) {
            return CTRLBUS_RX_NONE;
        }
#if CTRLBUS_DECODER_FAST == 1
        if (d->end == 0u) {
#else
        if (d->end == d->start) { /* (the compact core leaves `start` behind a frame handed out) */
#endif
            /* Nothing buffered (start is 0 too). Rule 1 first: garbage up to the next flag is
             * discarded, with one event per gap. */
#if DECODER_SHORTCUTS
            if ((in[0] | 0x40u) != CTRLBUS_FLAG_LONG) {
                if (d->buffer == NULL) {
                    return take_general(d, data, len, now_ms, frame);
                }
                size_t skip = 1;
                while (skip < n && (in[skip] | 0x40u) != CTRLBUS_FLAG_LONG) {
                    skip++;
                }
                if (d->stats != NULL) {
                    d->stats->bytes_discarded += (uint32_t)skip;
                }
                d->last_byte_ms = now_ms;
                *data = in + skip;
                *len = n - skip;
                if (!(d->state & STATE_EVENT_SINCE_FRAME)) {
                    return raise_event(d, CTRLBUS_RX_GARBAGE);
                }
                if (skip == n) {
                    return CTRLBUS_RX_NONE;
                }
                in += skip;
                n -= skip;
            }
#else
            if ((in[0] | 0x40u) != CTRLBUS_FLAG_LONG) {
                return take_general(d, data, len, now_ms, frame);
            }
#endif
            /* A candidate starts the input. */
            uint32_t header = header_size(in[0]);
            uint32_t len_field = n < header ? 0u : length_field(in, header);
            uint32_t size = header + len_field + 1u;
            if (size > d->max_frame) {
                return take_general(d, data, len, now_ms, frame);
            }
#if CTRLBUS_DECODER_FAST == 1
            if (n < header || size > n) {
#else
            if (size > n) { /* a header cut short too: with LEN taken as 0, size is header + 1 */
#endif
#if CTRLBUS_DECODER_FAST == 2
                /* the start of a frame that goes on beyond the input: buffer it all, at the
                 * front (the buffer has run empty: the flags of a span go) */
                d->start = d->end = 0;
                clear_flag(d, STATE_FLUSHING | STATE_IN_SPAN);
                append(d, in, n);
                d->complete_at = n < header ? 0u : size;
                d->last_byte_ms = now_ms;
                *data = in + n;
                *len = 0;
                return CTRLBUS_RX_NONE;
#else
                /* the start of a frame that goes on beyond the input: buffer it all */
                d->checksum = copy_xor(d->buffer, in, n, 0);
                d->end = (uint32_t)n;
                d->last_byte_ms = now_ms;
                d->complete_at = 0;
                *data = in + n;
                *len = 0;
                return CTRLBUS_RX_NONE;
#endif
            }
            /* a whole frame: checked in place, handed out without a copy */
            if (len_field == 0 || ctrlbus_xor_in_place_(in, size) != 0) {
                return take_general(d, data, len, now_ms, frame);
            }
            *data = in + size;
            *len = n - (size_t)size;
            return TAKE_FRAME(d, in, header, len_field, size, now_ms, frame);
        }
#if DECODER_SHORTCUTS
        /* More of the buffered candidate, when no timeout applies and it fits the buffer where
         * it lies. */
        uint32_t start = d->start;
        const uint8_t *cand = d->buffer + start;
        uint32_t header = header_size(cand[0]);
        uint32_t have = d->end - start;
        if (now_ms == d->last_byte_ms || !timed_out(d, now_ms)) {
            const uint8_t *head = cand;
            uint8_t split_header[3];
            if (have < header) {
                /* its header is split between the buffer and the input (and must fit where
                 * it lies: the general path moves a candidate at the buffer's end) */
                if (start + header > d->max_frame) {
                    return take_general(d, data, len, now_ms, frame);
                }
                if (n < header - have) {
                    d->checksum = copy_xor(d->buffer + d->end, in, n, d->checksum);
                    d->end += (uint32_t)n;
                    d->last_byte_ms = now_ms;
                    *data = in + n;
                    *len = 0;
                    return CTRLBUS_RX_NONE;
                }
                for (uint32_t i = 0; i < header; i++) {
                    split_header[i] = i < have ? cand[i] : in[i - have];
                }
                head = split_header;
            }
            uint32_t len_field = length_field(head, header);
            uint32_t complete_at = start + header + len_field + 1u;
            uint32_t need = complete_at - d->end;
            if (len_field != 0 && complete_at <= d->max_frame) {
                if (need > n) {
                    /* still not complete: buffer the input */
                    d->checksum = copy_xor(d->buffer + d->end, in, n, d->checksum);
                    d->end += (uint32_t)n;
                    d->last_byte_ms = now_ms;
                    *data = in + n;
                    *len = 0;
                    return CTRLBUS_RX_NONE;
                }
                if (copy_xor(d->buffer + d->end, in, (size_t)need, d->checksum) == 0) {
                    *data = in + need;
                    *len = n - (size_t)need;
                    return TAKE_FRAME(d, cand, header, len_field, complete_at, now_ms, frame);
                }
            }
        }
#endif
    }
#endif
    return take_general(d, data, len, now_ms, frame);
}

#if CTRLBUS_DECODER_FAST == 1
/* ---- push: one byte per call ---------------------------------------------------------------- */

/* Lets push()'s inline path take the next bytes when the decoder waits for more of a candidate
 * whose size is known, which fits the buffer where it is, has a command (LEN > 0), and needs at
 * least two more bytes (the last byte goes through push_slow(), which checks the frame). */
static void arm_inline_path(ctrlbus_decoder_t *d)
{
    d->complete_at = 0;
    uint32_t have = d->end - d->start;
    if ((d->state & STATE_WAITING) || have == 0) {
        return;
    }
    const uint8_t *cand = d->buffer + d->start;
    uint32_t header = header_size(cand[0]);
    if (have < header) {
        return;
    }
    uint32_t len_field = length_field(cand, header);
    uint32_t size = header + len_field + 1u;
    if (len_field != 0 && size <= d->max_frame - d->start && have < size) {
        d->complete_at = d->start + size;
    }
}

/* The byte that completes the armed candidate at `start`, which its checksum makes a frame with a
 * command: yield it and hand it out at once. Nothing else is buffered, so the buffer settles empty;
 * the frame's bytes stay where they are until the next call. */
static ctrlbus_rx_t push_last_byte(ctrlbus_decoder_t *d, uint8_t byte, ctrlbus_frame_t *frame)
{
    uint32_t start = d->start;
    const uint8_t *cand = d->buffer + start;
    d->buffer[d->end] = byte;
    uint32_t header = header_size(cand[0]);
    if (frame != NULL) {
        frame->is_long = header == 3u;
        frame->cmd = cand[header];
        frame->payload = cand + header + 1u;
        frame->payload_len = (size_t)(d->complete_at - start - header - 2u);
    }
    if (d->stats != NULL) {
        count(&d->stats->frames);
    }
    d->start = d->end = d->complete_at = 0;
    d->checksum = 0;
    clear_flag(d, STATE_EVENT_SINCE_FRAME | STATE_FLUSHING | STATE_IN_SPAN);
    return CTRLBUS_RX_FRAME;
}

/* Everything push_slow() does not settle itself (garbage, a failure, an empty frame, a full buffer,
 * an oversize length, a timeout): the general path, as a feed of one byte and the first result
 * after it. When a timeout applies before the byte, its results (the failure, then what the rescan
 * of the stale bytes finds) come out ahead of the byte, which waits at buffer[end] until they have
 * been taken (STATE_HELD; resume() takes it). */
RARE static ctrlbus_rx_t push_general(ctrlbus_decoder_t *d, uint8_t byte, uint32_t now_ms,
                                      ctrlbus_frame_t *frame)
{
    d->complete_at = 0;
    if (d->end == d->max_frame) {
        /* Room behind the waiting candidate (shorter than max_frame: start > 0), made before a
         * rescan can find a frame in it: a held byte then goes to buffer[0] without touching
         * the frame handed out. */
        move_to_front(d);
    }
    if (ctrlbus_decoder_feed(d, &byte, 1u, now_ms) == 0u) {
        d->buffer[d->end] = byte;
        set_flag(d, STATE_HELD);
        d->last_byte_ms = now_ms;
    }
    ctrlbus_rx_t rx = ctrlbus_decoder_next(d, frame);
    if (rx == CTRLBUS_RX_NONE) {
        arm_inline_path(d);
    }
    return rx;
}

/* A byte that is not a flag, with nothing buffered and nothing waiting: rule 1 as scan() applies
 * it (the byte is discarded; one garbage event per gap), settled here because garbage bursts come
 * byte by byte. The event is handed out at once, as ctrlbus_decoder_next() would. */
static ctrlbus_rx_t push_garbage(ctrlbus_decoder_t *d)
{
    if (d->stats != NULL) {
        count(&d->stats->bytes_discarded);
    }
    bool quiet = (d->state & (STATE_IN_SPAN | STATE_EVENT_SINCE_FRAME)) != 0;
    settle_empty(d);
    d->complete_at = 0;
    return quiet ? CTRLBUS_RX_NONE : raise_event(d, CTRLBUS_RX_GARBAGE);
}

/* complete_at - start for a long candidate armed at its flag: its first length byte takes push()'s
 * inline path and its second comes to push_slow(). No frame with a command is this short (a
 * standard frame with LEN 1 has 4 bytes, a long one 5), so it never means "the frame is complete".
 * The buffer is empty when a flag arrives, so start is 0 and these 3 bytes fit (max_frame >= 5). */
#define LONG_HEADER_ARMED CTRLBUS_DECODER_LONG_HEADER_ARMED_

ctrlbus_rx_t ctrlbus_decoder_push_slow(ctrlbus_decoder_t *decoder, uint8_t byte, uint32_t now_ms,
                                       ctrlbus_frame_t *frame)
{
    ctrlbus_decoder_t *d = decoder;
    if (d == NULL || d->buffer == NULL) {
        return CTRLBUS_RX_NONE;
    }
    if (d->state & STATE_WAITING) {
        return CTRLBUS_RX_BUSY;
    }
    uint32_t start = d->start;
    uint32_t end = d->end;
    if (now_ms != d->last_byte_ms) {
        if (end != start && timed_out(d, now_ms)) {
            return push_general(d, byte, now_ms, frame); /* the timeout first */
        }
        d->last_byte_ms = now_ms;
    }
    /* The common cases, each the same as scan() taking the byte; `arm` is complete_at after it. */
    uint32_t complete_at = d->complete_at;
    uint32_t arm = complete_at;
    if (complete_at != 0 && end + 1u < complete_at) {
        /* a byte inside an armed candidate, at a new millisecond */
    } else if (complete_at != 0 && complete_at - start != LONG_HEADER_ARMED) {
        if ((d->checksum ^ byte) != 0) {
            return push_general(d, byte, now_ms, frame); /* a checksum error */
        }
        return push_last_byte(d, byte, frame);
    } else if (end == start) {
        if ((byte | 0x40u) != CTRLBUS_FLAG_LONG) {
            return push_garbage(d);
        }
        /* a flag: a candidate starts (nothing buffered: start == end == 0, d->checksum == 0). A
         * long frame's first length byte can take the inline path. */
        arm = byte == CTRLBUS_FLAG_LONG && start == 0 ? LONG_HEADER_ARMED : 0u;
    } else {
        /* a byte behind a flag, the candidate's size not known yet */
        const uint8_t *cand = d->buffer + start;
        uint32_t have = end - start;
        uint32_t header = header_size(cand[0]);
        if (end == d->max_frame || have >= header) {
            return push_general(d, byte, now_ms, frame); /* a full buffer, or not armable */
        }
        arm = 0;
        if (have + 1u == header) {
            /* the header's last byte: the candidate's size is known */
            uint32_t len_field = header == 2u ? byte : (cand[1] | (uint32_t)byte << 8);
            uint32_t size = header + len_field + 1u;
            if (len_field == 0 || size > d->max_frame - start) {
                /* empty, oversize, or not fitting the buffer where it starts */
                return push_general(d, byte, now_ms, frame);
            }
            arm = start + size;
        }
    }
    d->buffer[end] = byte;
    d->end = end + 1u;
    d->checksum ^= byte;
    d->complete_at = arm;
    return CTRLBUS_RX_NONE;
}
#endif /* CTRLBUS_DECODER_FAST == 1 */
