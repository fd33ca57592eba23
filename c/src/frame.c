/* Frame layer: streaming encoder and streaming decoder (see ctrlbus/frame.h). */
#include "ctrlbus/frame.h"

#include <string.h>

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

/* Sends bytes that belong to the frame (everything but the checksum) and folds them into it. */
static void sink_emit(ctrlbus_sink_t *sink, const uint8_t *data, size_t len)
{
    if (sink->status != CTRLBUS_OK || len == 0) {
        return;
    }
    int32_t result = sink->write(sink->context, data, len);
    if (result < 0) {
        sink->status = result;
        return;
    }
    sink->checksum = xor_bytes(sink->checksum, data, len);
}

int32_t ctrlbus_sink_begin(ctrlbus_sink_t *sink, uint8_t cmd, size_t payload_len,
                           ctrlbus_frame_type_t type)
{
    if (sink == NULL || sink->write == NULL) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    sink->in_frame = 0;
    int32_t frame_len = ctrlbus_frame_size(payload_len, type);
    if (frame_len < 0) {
        sink->status = frame_len;
        return frame_len;
    }
    /* From here payload_len <= 65534, so the narrowing casts below are exact. */
    uint8_t header[4];
    size_t header_len;
    uint32_t len_field = (uint32_t)payload_len + 1u;
    bool is_long = type == CTRLBUS_FRAME_LONG ||
                   (type == CTRLBUS_FRAME_AUTO && payload_len > CTRLBUS_STANDARD_PAYLOAD_MAX);
    if (!is_long) {
        header[0] = CTRLBUS_FLAG_STANDARD;
        header[1] = (uint8_t)len_field;
        header[2] = cmd;
        header_len = 3;
    } else {
        header[0] = CTRLBUS_FLAG_LONG;
        header[1] = (uint8_t)(len_field & 0xFFu);
        header[2] = (uint8_t)(len_field >> 8);
        header[3] = cmd;
        header_len = 4;
    }
    sink->status = CTRLBUS_OK;
    sink->checksum = 0;
    sink->frame_len = (uint32_t)frame_len;
    sink->remaining = (uint32_t)payload_len;
    sink->in_frame = 1;
    sink_emit(sink, header, header_len);
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
    if (!sink->in_frame || len > sink->remaining || data == NULL) {
        ctrlbus_sink_fail(sink, data == NULL ? CTRLBUS_ERR_ARGUMENT : CTRLBUS_ERR_LENGTH);
        return;
    }
    sink->remaining -= (uint32_t)len;
    sink_emit(sink, data, len);
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
        ctrlbus_sink_fail(sink, CTRLBUS_ERR_LENGTH);
    } else if (sink->remaining != 0) {
        ctrlbus_sink_fail(sink, CTRLBUS_ERR_LENGTH);
    }
    sink->in_frame = 0;
    if (sink->status != CTRLBUS_OK) {
        return sink->status;
    }
    uint8_t checksum = sink->checksum;
    int32_t result = sink->write(sink->context, &checksum, 1);
    if (result < 0) {
        sink->status = result;
        return result;
    }
    return (int32_t)sink->frame_len;
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

static void count(uint32_t *counter)
{
    *counter += 1u;
}

int32_t ctrlbus_decoder_init(ctrlbus_decoder_t *decoder, uint8_t *buffer, size_t buffer_size,
                             uint16_t timeout_ms, ctrlbus_decoder_stats_t *stats)
{
    if (decoder == NULL || buffer == NULL || buffer_size < CTRLBUS_DECODER_BUFFER_MIN) {
        return CTRLBUS_ERR_ARGUMENT;
    }
    decoder->buffer = buffer;
    decoder->stats = stats;
    decoder->max_frame =
        buffer_size > CTRLBUS_FRAME_MAX ? CTRLBUS_FRAME_MAX : (uint32_t)buffer_size;
    decoder->timeout_ms = timeout_ms;
    decoder->last_byte_ms = 0;
    if (stats != NULL) {
        /* Field by field, so that no memset is pulled in on an MCU. */
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
    decoder->checksum = 0;
    decoder->state = 0;
}

bool ctrlbus_decoder_busy(const ctrlbus_decoder_t *decoder)
{
    return decoder != NULL && decoder->end > decoder->start;
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
    default: return "unknown";
    }
}

/* Records an event (rule 1's "an event was raised since the last frame") and returns it. */
static ctrlbus_rx_t raise_event(ctrlbus_decoder_t *d, ctrlbus_rx_t event)
{
    set_flag(d, STATE_EVENT_SINCE_FRAME);
    return event;
}

/* Rule 4: the candidate at `start` failed. Counts it, drops its flag byte and makes everything
 * still buffered its span. Returns true when the failure is outermost, so its event is raised. */
static bool fail_candidate(ctrlbus_decoder_t *d, ctrlbus_rx_t kind)
{
    bool outermost = !(d->state & STATE_IN_SPAN);
    ctrlbus_decoder_stats_t *stats = d->stats;
    if (stats != NULL) {
        count(kind == CTRLBUS_RX_CHECKSUM_ERROR ? &stats->checksum_errors
              : kind == CTRLBUS_RX_OVERSIZE     ? &stats->oversize
                                                : &stats->timeouts);
        count(&stats->resyncs);
        count(&stats->bytes_discarded);
    }
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

/* Scans buffered bytes from offset `pos`, where d->checksum is the XOR of buffer[start..pos),
 * until a result is found (returned, not yet recorded as pending) or more bytes are needed
 * (CTRLBUS_RX_NONE, with d->checksum covering buffer[start..end)). A yielded frame stays at
 * `start`; ctrlbus_decoder_next() steps over it when it hands it out. */
static ctrlbus_rx_t scan(ctrlbus_decoder_t *d, uint32_t pos)
{
    const uint8_t *buf = d->buffer;
    for (;; pos = d->start) {
        uint32_t avail = d->end - d->start;
        if (avail == 0) {
            /* Nothing buffered: restart at the front, which keeps later frames contiguous. */
            d->start = d->end = 0;
            d->checksum = 0;
            clear_flag(d, STATE_FLUSHING | STATE_IN_SPAN);
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
        uint32_t header = flag == CTRLBUS_FLAG_STANDARD ? 2u : 3u;
        ctrlbus_rx_t failure = CTRLBUS_RX_NONE;
        if (avail >= header) {
            uint32_t len_field = buf[d->start + 1];
            if (header == 3u) {
                len_field |= (uint32_t)buf[d->start + 2] << 8;
            }
            uint32_t size = header + len_field + 1u;
            if (size > d->max_frame) {
                failure = CTRLBUS_RX_OVERSIZE;
            } else if (avail >= size) {
                uint32_t last = d->start + size - 1u;
                if (xor_bytes(d->checksum, buf + pos, last - pos) != buf[last]) {
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
                    if (d->stats != NULL) {
                        count(&d->stats->frames);
                    }
                    clear_flag(d, STATE_EVENT_SINCE_FRAME);
                    return CTRLBUS_RX_FRAME;
                }
            }
        }
        if (failure == CTRLBUS_RX_NONE) {
            if (!(d->state & STATE_FLUSHING)) {
                /* Incomplete: remember the checksum so far and wait for more bytes. */
                d->checksum = xor_bytes(d->checksum, buf + pos, d->end - pos);
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

/* Finishes a rescan that a taken result interrupted. Returns its result (or NONE). */
static ctrlbus_rx_t resume(ctrlbus_decoder_t *d)
{
    if (!(d->state & STATE_RESCAN)) {
        return CTRLBUS_RX_NONE;
    }
    clear_flag(d, STATE_RESCAN);
    d->checksum = 0;
    return scan(d, d->start);
}

/* Rule 5, checked before new bytes are taken. Returns a result to hold, or NONE. */
static ctrlbus_rx_t apply_timeout(ctrlbus_decoder_t *d, uint32_t now_ms)
{
    uint32_t elapsed = now_ms - d->last_byte_ms;
    if (d->timeout_ms == 0 || d->end == d->start || elapsed <= d->timeout_ms ||
        elapsed >= TIME_BACKWARDS) {
        return CTRLBUS_RX_NONE;
    }
    set_flag(d, STATE_FLUSHING);
    if (fail_candidate(d, CTRLBUS_RX_TIMEOUT)) {
        return raise_event(d, CTRLBUS_RX_TIMEOUT); /* the stale bytes are rescanned after it */
    }
    return scan(d, d->start);
}

size_t ctrlbus_decoder_feed(ctrlbus_decoder_t *decoder, const uint8_t *data, size_t len,
                            uint32_t now_ms)
{
    ctrlbus_decoder_t *d = decoder;
    if (d == NULL || d->buffer == NULL) {
        return len; /* nowhere to put them: report them taken so a caller's loop ends */
    }
    if ((d->state & STATE_PENDING_MASK) != 0) {
        return 0;
    }
    if (hold(d, resume(d)) || hold(d, apply_timeout(d, now_ms))) {
        return 0;
    }
    if (data == NULL) {
        return len; /* no bytes: report them all taken so a caller's loop ends */
    }
    for (size_t used = 0; used < len;) {
        if (d->end == d->max_frame) {
            /* Full: move the partial candidate to the front. While waiting, it is shorter than
             * max_frame (it would have completed or failed otherwise), so start > 0 here. */
            uint32_t keep = d->end - d->start;
            for (uint32_t i = 0; i < keep; i++) { /* a plain loop: no libc needed on an MCU */
                d->buffer[i] = d->buffer[d->start + i];
            }
            d->start = 0;
            d->end = keep;
        }
        d->buffer[d->end++] = data[used++];
        d->last_byte_ms = now_ms;
        if (hold(d, scan(d, d->end - 1u))) {
            return used;
        }
    }
    return len;
}

void ctrlbus_decoder_tick(ctrlbus_decoder_t *decoder, uint32_t now_ms)
{
    (void)ctrlbus_decoder_feed(decoder, NULL, 0, now_ms);
}

ctrlbus_rx_t ctrlbus_decoder_next(ctrlbus_decoder_t *decoder, ctrlbus_frame_t *frame)
{
    ctrlbus_decoder_t *d = decoder;
    if (d == NULL || d->buffer == NULL) {
        return CTRLBUS_RX_NONE;
    }
    ctrlbus_rx_t rx = (ctrlbus_rx_t)(d->state & STATE_PENDING_MASK);
    if (rx == CTRLBUS_RX_NONE) {
        rx = resume(d);
        if (rx == CTRLBUS_RX_NONE) {
            return CTRLBUS_RX_NONE;
        }
    }
    d->state = (uint8_t)((d->state & (uint8_t)~STATE_PENDING_MASK) | STATE_RESCAN);
    if (rx == CTRLBUS_RX_FRAME) {
        const uint8_t *bytes = d->buffer + d->start;
        bool is_long = bytes[0] == CTRLBUS_FLAG_LONG;
        uint32_t len_field = is_long ? ((uint32_t)bytes[1] | ((uint32_t)bytes[2] << 8)) : bytes[1];
        uint32_t header = is_long ? 3u : 2u;
        if (frame != NULL) {
            frame->is_long = is_long;
            frame->cmd = bytes[header];
            frame->payload = bytes + header + 1u;
            frame->payload_len = len_field - 1u;
        }
        d->start += header + len_field + 1u;
    }
    return rx;
}
