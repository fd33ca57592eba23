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

/* ---- decoder -------------------------------------------------------------------------------- *
 *
 * One core for every build, byte path and chunk path alike. On a clean link it is a plain state
 * machine: a candidate's size is known once its header is in, and the bytes up to that size are
 * appended with no further look (push(): a comparison and a store per byte; feed() and take(): one
 * copy per run). A candidate's checksum is the XOR of its bytes, taken once when it is complete.
 * Only when a candidate fails (or a header, garbage or a timeout needs a decision) does scan() look
 * at the bytes it holds, restarting after the failed flag (rule D4, backtracking).
 *
 * The scan advances `start` over the bytes it drops (and next() over a frame it hands out); a
 * scan that ends waiting for more bytes moves its incomplete candidate to the front of the buffer,
 * where new bytes have room behind it (a waiting candidate is shorter than max_frame, so the byte
 * after it always fits). d->complete_at holds the size of the frame found (for next()) or, after a
 * scan that found nothing, the size of the incomplete candidate at the front once its header is
 * buffered (0 otherwise, and after next() hands out a frame): push() and feed() append up to it
 * without a scan. d->checksum holds the byte that STATE_HELD keeps. Between calls only an
 * incomplete candidate (or nothing) is buffered, so a scan that finds nothing new costs O(1). A
 * result found is held in the state until next() hands it out; after that STATE_RESCAN says that
 * more may wait in the buffered bytes. */

/* For a rare path: kept out of its caller, which then stays small. */
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
/* ctrlbus_decoder_push() took a byte while a timeout applied before it: the byte waits in
 * d->checksum until the results of the timeout have been taken. */
#define STATE_HELD 0x80u
/* Results or work that must come before any new byte. */
#define STATE_WAITING (STATE_PENDING_MASK | STATE_RESCAN | STATE_HELD)

/* Time gaps at or beyond this are taken as "the clock went backwards" rather than a long wait. */
#define TIME_BACKWARDS 0x80000000u

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

/* Whether a machine word may be read at any alignment with a plain load. Not on ARMv6-M
 * (Cortex-M0/M0+) and other ARM cores without unaligned access: there memcpy of a word is a call,
 * slower than reading bytes. */
#if defined(__arm__) && !defined(__ARM_FEATURE_UNALIGNED)
#define WORD_READS 0
#else
#define WORD_READS 1
#endif

/* The XOR of a complete candidate's bytes (0 for a right checksum): a machine word at a time
 * through memcpy (safe at any alignment; compilers make plain loads of it) where words can be read
 * unaligned, byte by byte elsewhere. */
static uint8_t candidate_xor(const uint8_t *bytes, uint32_t n)
{
    size_t acc = 0; /* the XOR of the bytes read, lane by lane */
    const uint8_t *end = bytes + n;
    for (; WORD_READS && (size_t)(end - bytes) >= sizeof acc; bytes += sizeof acc) {
        size_t word;
        memcpy(&word, bytes, sizeof word);
        acc ^= word;
    }
    for (; bytes < end; bytes++) {
        acc ^= *bytes;
    }
    for (unsigned shift = (unsigned)sizeof acc * 4u; shift >= 8u; shift /= 2u) {
        acc ^= acc >> shift; /* fold: the low byte becomes the XOR of all the lanes */
    }
    return (uint8_t)acc;
}

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

/* Fills in *frame (when not NULL) for the frame of `size` bytes at bytes[0..). */
RARE static void describe_frame(ctrlbus_frame_t *frame, const uint8_t *bytes, uint32_t size)
{
    if (frame != NULL) {
        uint32_t header = header_size(bytes[0]);
        frame->is_long = header == 3u;
        frame->cmd = bytes[header];
        frame->payload = bytes + header + 1u;
        frame->payload_len = (size_t)(size - header - 2u);
    }
}

/* push() and take() hand out the frame of `size` bytes at bytes[0..) (in the buffer or in the
 * caller's bytes) at once, with nothing else buffered or waiting: what the scan and next() would
 * do, the buffer then running empty (rules 2-3). */
RARE static ctrlbus_rx_t take_frame(ctrlbus_decoder_t *d, const uint8_t *bytes, uint32_t size,
                                    ctrlbus_frame_t *frame)
{
    describe_frame(frame, bytes, size);
    add_count(d, CTRLBUS_RX_FRAME, 1u);
    d->start = d->end = d->complete_at = 0;
    d->checksum = 0;
    clear_flag(d, STATE_EVENT_SINCE_FRAME | STATE_FLUSHING | STATE_IN_SPAN);
    return CTRLBUS_RX_FRAME;
}

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
    } else if (d->start == 0u && !(d->state & STATE_WAITING)) {
        /* Nothing waits and what is buffered is at the front (not behind a result handed out):
         * an incomplete candidate, or nothing, on which a scan would change nothing. */
        return false;
    }
    return scan(d);
}

/* Appends n (> 0) bytes behind the buffered ones (a plain loop: no libc needed on an MCU). */
static void append(ctrlbus_decoder_t *d, const uint8_t *bytes, size_t n)
{
    uint8_t *dst = d->buffer + d->end;
    const uint8_t *stop = bytes + n;
    d->end += (uint32_t)n;
    while (bytes != stop) {
        *dst++ = *bytes++;
    }
}

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
        if (d->end < d->complete_at) {
            continue; /* still short of its size: a scan would find what it found before */
        }
        if (scan(d)) {
            return used;
        }
    }
    return len;
}

/* (Not a feed of no bytes, so that a program linking push, next and tick leaves feed out; the
 * base stack, which links feed, takes the timeout with a feed of no bytes instead.) */
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
        /* Nothing to resume: every call that takes bytes has settled them as a scan would. */
        if (!(d->state & (STATE_RESCAN | STATE_HELD))) {
            return CTRLBUS_RX_NONE;
        }
        (void)scan(d);
    }
    ctrlbus_rx_t rx = (ctrlbus_rx_t)(d->state & STATE_PENDING_MASK);
    clear_flag(d, STATE_PENDING_MASK);
    if (rx == CTRLBUS_RX_FRAME) {
        /* The frame lies at `start`; scanning resumes after it at the next call. */
        uint32_t size = d->complete_at;
        describe_frame(frame, d->buffer + d->start, size);
        d->start += size;
        d->complete_at = 0u; /* push() appends again only after a scan */
    }
    if (rx != CTRLBUS_RX_NONE && (d->start != d->end || (d->state & STATE_HELD))) {
        set_flag(d, STATE_RESCAN); /* more results may wait in the bytes still buffered */
    }
    return rx;
}

/* ctrlbus_decoder_push() for every byte but those inside a candidate whose size is known (its
 * own function, so that the common byte's path saves no registers). */
RARE static ctrlbus_rx_t push_settle(ctrlbus_decoder_t *d, uint8_t byte, uint32_t now_ms,
                                     ctrlbus_frame_t *frame)
{
    if (d == NULL || d->buffer == NULL) {
        return CTRLBUS_RX_NONE;
    }
    if (d->state & STATE_WAITING) {
        return CTRLBUS_RX_BUSY;
    }
    if (results_first(d, now_ms)) {
        /* A timeout applied before the byte, and its results come first: the byte waits behind
         * the stale bytes (see STATE_HELD) and goes in when they are used up. */
        d->checksum = byte;
        set_flag(d, STATE_HELD);
    } else {
        d->buffer[d->end++] = byte; /* as a feed of one byte */
        d->last_byte_ms = now_ms;
        if (!scan(d)) {
            return CTRLBUS_RX_NONE;
        }
    }
    d->last_byte_ms = now_ms;
    return ctrlbus_decoder_next(d, frame);
}

ctrlbus_rx_t ctrlbus_decoder_push(ctrlbus_decoder_t *decoder, uint8_t byte, uint32_t now_ms,
                                  ctrlbus_frame_t *frame)
{
    /* The clean path: a byte inside a candidate whose size is known (complete_at is 0 unless it
     * is, nothing waits and it fits where it lies), at the same millisecond as the byte before
     * it, so no timeout to apply. */
    if (decoder != NULL) {
        uint32_t end = decoder->end;
        if (end + 1u < decoder->complete_at && now_ms == decoder->last_byte_ms) {
            decoder->buffer[end] = byte;
            decoder->end = end + 1u;
            return CTRLBUS_RX_NONE;
        }
    }
    return push_settle(decoder, byte, now_ms, frame);
}

/* ctrlbus_decoder_take() in general: results first, then feeds, as its contract spells out. */
RARE static ctrlbus_rx_t take_general(ctrlbus_decoder_t *d, const uint8_t **data, size_t *len,
                                      uint32_t now_ms, ctrlbus_frame_t *frame)
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

ctrlbus_rx_t ctrlbus_decoder_take(ctrlbus_decoder_t *decoder, const uint8_t **data, size_t *len,
                                  uint32_t now_ms, ctrlbus_frame_t *frame)
{
    ctrlbus_decoder_t *d = decoder;
    if (d == NULL || data == NULL || len == NULL) {
        return CTRLBUS_RX_NONE;
    }
    /* With nothing buffered or waiting, a whole frame at the start of the input is checked and
     * handed out in place, and a frame's start is buffered in one copy; anything else is settled
     * by feed() and next() (a decoder never initialised has max_frame 0: take_general()). */
    const uint8_t *in = *data;
    size_t n = *len;
    if (!(d->state & STATE_WAITING) && in != NULL && d->end == d->start) {
        if (n == 0) {
            return CTRLBUS_RX_NONE;
        }
        if ((in[0] | 0x40u) == CTRLBUS_FLAG_LONG) {
            uint32_t header = header_size(in[0]);
            uint32_t len_field = n < header ? 0u : length_field(in, header);
            uint32_t size = header + len_field + 1u; /* a header cut short: header + 1 */
            if (size > d->max_frame) {
                return take_general(d, data, len, now_ms, frame);
            }
            d->last_byte_ms = now_ms;
            if (size > n) {
                /* the start of a frame that goes on beyond the input: buffer it all, at the
                 * front (the buffer has run empty: the flags of a span go) */
                d->start = d->end = 0;
                clear_flag(d, STATE_FLUSHING | STATE_IN_SPAN);
                append(d, in, n);
                d->complete_at = n < header ? 0u : size;
                *data = in + n;
                *len = 0;
                return CTRLBUS_RX_NONE;
            }
            if (len_field != 0 && candidate_xor(in, size) == 0) {
                *data = in + size;
                *len = n - (size_t)size;
                return take_frame(d, in, size, frame);
            }
        }
    } else if (!(d->state & STATE_WAITING) && in != NULL && n != 0 && d->start == 0u &&
               d->complete_at > d->end && (now_ms == d->last_byte_ms || !timed_out(d, now_ms))) {
        /* More of the candidate at the front whose size is known, with no timeout to apply: the
         * bytes up to its end go in as one run, as feed() would take them. */
        uint32_t size = d->complete_at;
        size_t run = (size_t)(size - d->end);
        if (run > n) {
            run = n;
        }
        append(d, in, run);
        d->last_byte_ms = now_ms;
        *data = in + run;
        *len = n - run;
        if (d->end < size) {
            return CTRLBUS_RX_NONE;
        }
        if (size > header_size(d->buffer[0]) + 1u && candidate_xor(d->buffer, size) == 0u) {
            return take_frame(d, d->buffer, size, frame);
        }
        (void)scan(d); /* LEN 0 or a checksum error: the scan settles it, next() hands it out */
    }
    return take_general(d, data, len, now_ms, frame);
}
