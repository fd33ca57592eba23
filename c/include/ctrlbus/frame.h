/* SPDX-License-Identifier: MIT */
/* ctrlbus frame layer: the streaming encoder ("sink") and the streaming decoder.
 *
 * A frame on the wire (docs/protocol.md has the full text):
 *
 *   standard: 0x10  LEN                CMD  PAYLOAD[LEN-1]  CHECKSUM
 *   long:     0x50  LEN_LO  LEN_HI     CMD  PAYLOAD[LEN-1]  CHECKSUM
 *
 * LEN counts CMD plus the payload; CHECKSUM is the XOR of every byte from the flag through the
 * last payload byte. A standard frame carries at most 254 payload bytes, a long one 65534.
 *
 * Encoding never needs a transmit buffer: a sink streams the frame through a write callback while
 * it keeps the running checksum, so a base can answer straight into its UART. Encoding into a
 * caller buffer is the same code with ctrlbus_buffer_write() as the callback.
 *
 * Decoding is incremental: the caller pushes received bytes with ctrlbus_decoder_feed() and takes
 * the results (frames and events, in stream order) with ctrlbus_decoder_next(); or one byte at a
 * time with ctrlbus_decoder_push() (a UART interrupt's byte), or a chunk with
 * ctrlbus_decoder_take() (a DMA or ring buffer's bytes), which return the results themselves. The
 * decoder follows the contract in vectors/README.md exactly ("The stream decoder, precisely"),
 * whichever calls feed it.
 */
#ifndef CTRLBUS_FRAME_H
#define CTRLBUS_FRAME_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>
#include <string.h>

#include "ctrlbus/ctrlbus.h"

#ifdef __cplusplus
extern "C" {
#endif

#define CTRLBUS_FLAG_STANDARD 0x10u
#define CTRLBUS_FLAG_LONG 0x50u
/* Bytes around the payload: flag + length + CMD before it, checksum after it. */
#define CTRLBUS_STANDARD_OVERHEAD 4u
#define CTRLBUS_LONG_OVERHEAD 5u
/* The largest payload each frame type can carry (LEN = payload + 1). */
#define CTRLBUS_STANDARD_PAYLOAD_MAX 254u
#define CTRLBUS_LONG_PAYLOAD_MAX 65534u
/* The largest whole frame (a long frame with LEN 65535): the decoder's default max_frame. */
#define CTRLBUS_FRAME_MAX 65539u
/* The smallest decoder buffer: a frame with a one-byte payload fits. */
#define CTRLBUS_DECODER_BUFFER_MIN 5u
/* A good inter-byte timeout for a base on an MCU (bytes arrive at wire pace). Hosts reading
 * through USB-serial adapters need 50-100 ms. */
#define CTRLBUS_DEFAULT_TIMEOUT_MS 10u

/* Which flag to write. AUTO (zero, the default) picks a standard frame when the payload fits in
 * one and a long frame otherwise. */
typedef enum {
    CTRLBUS_FRAME_AUTO = 0,
    CTRLBUS_FRAME_STANDARD = 1,
    CTRLBUS_FRAME_LONG = 2
} ctrlbus_frame_type_t;

/* ------------------------------------------------------------------------------------------------
 * Encoder
 * --------------------------------------------------------------------------------------------- */

/* Delivers len bytes somewhere (a UART, a socket, a buffer). Returns 0 when all were taken, or a
 * negative error (CTRLBUS_ERR_IO is a good choice); the sink then stops writing and reports that
 * error from ctrlbus_sink_end(). It is called several times per frame, with short pieces. */
typedef int32_t (*ctrlbus_write_fn)(void *context, const uint8_t *data, size_t len);

/* A frame being written. Caller-owned, usually a local variable: it only lives while one frame (or
 * a series of frames) is written. Treat the fields as private. */
typedef struct {
    ctrlbus_write_fn write;
    void *context;
    uint32_t frame_len; /* whole size of the current frame (kept by ctrlbus_sink_begin()) */
    int32_t status;     /* the first error, sticky until the next ctrlbus_sink_begin() */
    uint16_t remaining; /* payload bytes still to come in the current frame (at most 65534) */
    uint8_t checksum;   /* XOR of everything written in the current frame */
    uint8_t in_frame;
} ctrlbus_sink_t;

/* A caller-owned byte array that a sink can write into (see ctrlbus_buffer_write()). */
typedef struct {
    uint8_t *data;
    size_t size; /* capacity of data */
    size_t len;  /* bytes written so far */
} ctrlbus_buffer_t;

/* Prepares a sink that writes through write(context, ...). Returns CTRLBUS_OK, or
 * CTRLBUS_ERR_ARGUMENT when sink or write is NULL. ISR-safe. Cost: O(1). */
int32_t ctrlbus_sink_init(ctrlbus_sink_t *sink, ctrlbus_write_fn write, void *context);

/* Starts a frame: writes the flag, the length and cmd. Exactly payload_len bytes must follow
 * through the ctrlbus_sink_put*() functions before ctrlbus_sink_end().
 * Returns CTRLBUS_OK; CTRLBUS_ERR_TOO_BIG when payload_len does not fit the frame type (more than
 * 254 for STANDARD, more than 65534 for any); CTRLBUS_ERR_ARGUMENT for a NULL sink or an unknown
 * type; or the write callback's error. A previous frame left unfinished is abandoned.
 * ISR-safe if the write callback is. Cost: O(1) plus one write call. */
int32_t ctrlbus_sink_begin(ctrlbus_sink_t *sink, uint8_t cmd, size_t payload_len,
                           ctrlbus_frame_type_t type);

/* Writes payload bytes of the current frame. These return nothing: an error (a write callback
 * failure, more bytes than announced, no frame begun) is kept in the sink and reported by
 * ctrlbus_sink_end(); after an error nothing more is written. Multi-byte values are little-endian.
 * ISR-safe if the write callback is. Cost: O(n) for n bytes plus one write call. */
void ctrlbus_sink_put(ctrlbus_sink_t *sink, const uint8_t *data, size_t len);
void ctrlbus_sink_put_u8(ctrlbus_sink_t *sink, uint8_t value);
void ctrlbus_sink_put_u16(ctrlbus_sink_t *sink, uint16_t value);
void ctrlbus_sink_put_u32(ctrlbus_sink_t *sink, uint32_t value);
void ctrlbus_sink_put_s32(ctrlbus_sink_t *sink, int32_t value);
/* Writes a text field of exactly field_size bytes: the characters of text up to its first NUL (at
 * most field_size of them), then NUL padding. A NULL text writes field_size NULs. */
void ctrlbus_sink_put_text(ctrlbus_sink_t *sink, const char *text, size_t field_size);
/* Records an error found by an encoder (for example CTRLBUS_ERR_ARGUMENT for a contradictory
 * struct); the frame is then reported as failed by ctrlbus_sink_end(). ISR-safe. Cost: O(1). */
void ctrlbus_sink_fail(ctrlbus_sink_t *sink, int32_t error);

/* Ends the frame by writing its checksum. Returns the whole frame's size in bytes, or the first
 * error of the frame: CTRLBUS_ERR_LENGTH when fewer or more payload bytes were put than announced
 * (no checksum is written then), the write callback's error, or an encoder's error. A frame that
 * failed half-way may have been partly written already; a buffer sink can simply be reset.
 * ISR-safe if the write callback is. Cost: O(1) plus one write call. */
int32_t ctrlbus_sink_end(ctrlbus_sink_t *sink);

/* A ctrlbus_write_fn that appends to the ctrlbus_buffer_t passed as context. Returns
 * CTRLBUS_ERR_TOO_BIG (and writes nothing) when the bytes do not fit. ISR-safe. Cost: O(len). */
int32_t ctrlbus_buffer_write(void *context, const uint8_t *data, size_t len);

/* Points sink at buffer, which is set to write into data[0..size). Returns CTRLBUS_OK or
 * CTRLBUS_ERR_ARGUMENT (a NULL pointer). ISR-safe. Cost: O(1). */
int32_t ctrlbus_sink_init_buffer(ctrlbus_sink_t *sink, ctrlbus_buffer_t *buffer, uint8_t *data,
                                 size_t size);

/* Writes one whole frame (cmd + payload) through sink: begin, put, end in one call. Returns the
 * frame's size or a negative error as ctrlbus_sink_begin()/ctrlbus_sink_end() do. payload may be
 * NULL when payload_len is 0. ISR-safe if the write callback is. Cost: O(payload_len).
 *
 * A base answers SYNC and ECHO with a verbatim copy of the request: writing the decoded frame's
 * cmd and payload back with the same type (LONG if it was long, else STANDARD) gives exactly the
 * request's bytes, checksum included. */
int32_t ctrlbus_frame_write(ctrlbus_sink_t *sink, uint8_t cmd, const uint8_t *payload,
                            size_t payload_len, ctrlbus_frame_type_t type);

/* Encodes one whole frame into out[0..out_size). Returns the frame's size, CTRLBUS_ERR_TOO_BIG
 * when it does not fit in out (or in a frame of that type), or CTRLBUS_ERR_ARGUMENT.
 * ISR-safe. Cost: O(payload_len). */
int32_t ctrlbus_frame_encode(uint8_t *out, size_t out_size, uint8_t cmd, const uint8_t *payload,
                             size_t payload_len, ctrlbus_frame_type_t type);

/* The size of the frame that carries payload_len bytes with the given type, or CTRLBUS_ERR_TOO_BIG
 * when it cannot. ISR-safe. Cost: O(1). */
int32_t ctrlbus_frame_size(size_t payload_len, ctrlbus_frame_type_t type);

/* ------------------------------------------------------------------------------------------------
 * Decoder
 * --------------------------------------------------------------------------------------------- */

/* What ctrlbus_decoder_next() hands out. FRAME is a valid frame; the others are the contract's
 * events, which a base answers (garbage: ERROR 0x0010, checksum_error: 0x0040, oversize: 0x0020,
 * empty_frame: 0x8001, timeout: nothing). */
typedef enum {
    CTRLBUS_RX_NONE = 0,           /* nothing more until more bytes (or time) arrive */
    CTRLBUS_RX_FRAME = 1,          /* a frame: see the ctrlbus_frame_t */
    CTRLBUS_RX_GARBAGE = 2,        /* bytes outside any frame (once per gap, see the rules) */
    CTRLBUS_RX_CHECKSUM_ERROR = 3, /* a candidate frame whose checksum did not match */
    CTRLBUS_RX_OVERSIZE = 4,       /* a candidate frame longer than the buffer */
    CTRLBUS_RX_TIMEOUT = 5,        /* a partial frame dropped after the inter-byte timeout */
    CTRLBUS_RX_EMPTY_FRAME = 6,    /* a well-formed frame with LEN 0: it has no command */
    CTRLBUS_RX_BUSY = 7 /* ctrlbus_decoder_push() only: results were still waiting, so the byte
                         * was NOT taken; take them with ctrlbus_decoder_next(), then push it again */
} ctrlbus_rx_t;

/* A decoded frame. payload points into the decoder's buffer and stays valid until the next call of
 * ctrlbus_decoder_feed(), ctrlbus_decoder_next(), ctrlbus_decoder_tick() or
 * ctrlbus_decoder_reset() on that decoder. */
typedef struct {
    const uint8_t *payload;
    size_t payload_len; /* 0..65534 */
    uint8_t cmd;
    bool is_long; /* the frame had the 0x50 flag */
} ctrlbus_frame_t;

/* The decoder's counters (names as in the contract). Caller-owned and optional: pass NULL to
 * ctrlbus_decoder_init() to count nothing. They wrap around at 2^32. */
typedef struct {
    uint32_t frames;          /* frames yielded */
    uint32_t bytes_discarded; /* bytes that were not part of a yielded frame */
    uint32_t checksum_errors; /* candidates failed by their checksum */
    uint32_t oversize;        /* candidates failed by a length over max_frame */
    uint32_t timeouts;        /* candidates failed by the inter-byte timeout */
    uint32_t empty_frames;    /* well-formed LEN = 0 frames */
    uint32_t resyncs;         /* failed candidates of any kind */
} ctrlbus_decoder_stats_t;

/* The decoder state: 32 bytes on a 32-bit target, besides the caller's buffer (and the optional
 * stats). Caller-owned; treat the fields as private. Offsets are uint32_t because a buffer may hold
 * a whole long frame of 65539 bytes. */
typedef struct {
    uint8_t *buffer;
    ctrlbus_decoder_stats_t *stats;
    uint32_t max_frame;    /* usable buffer size, at most CTRLBUS_FRAME_MAX */
    uint32_t start;        /* first byte of the current candidate */
    uint32_t end;          /* one past the last buffered byte */
    uint32_t complete_at;  /* the `end` that completes the buffered candidate once its size is
                            * known, or the size of a frame waiting for next(); else 0 */
    uint32_t last_byte_ms; /* time of the last byte fed */
    uint16_t timeout_ms;   /* 0 = no inter-byte timeout */
    uint8_t checksum;      /* a byte push() holds behind a timeout's results */
    uint8_t state;         /* pending result and flags, see frame.c */
} ctrlbus_decoder_t;

/* Prepares a decoder over the caller's buffer. max_frame (the largest whole frame accepted,
 * header and checksum included) is buffer_size, capped at CTRLBUS_FRAME_MAX; a longer candidate
 * fails as oversize. timeout_ms is the inter-byte timeout (0 = off; CTRLBUS_DEFAULT_TIMEOUT_MS is
 * a good value for an MCU). stats may be NULL; otherwise it is zeroed and then counted into.
 * Returns CTRLBUS_OK, or CTRLBUS_ERR_ARGUMENT for a NULL decoder/buffer or a buffer smaller than
 * CTRLBUS_DECODER_BUFFER_MIN. ISR-safe. Cost: O(1). */
int32_t ctrlbus_decoder_init(ctrlbus_decoder_t *decoder, uint8_t *buffer, size_t buffer_size,
                             uint16_t timeout_ms, ctrlbus_decoder_stats_t *stats);

/* Forgets every buffered byte and any result not yet taken (counters and settings are kept), as if
 * the link had just been opened. ISR-safe. Cost: O(1). */
void ctrlbus_decoder_reset(ctrlbus_decoder_t *decoder);

/* Pushes received bytes, all stamped with the time now_ms (a free-running millisecond clock that
 * may wrap around at 2^32; it must not run backwards, and a gap between calls must stay below
 * 2^31 ms, about 24 days). Before taking any byte it applies the inter-byte timeout at now_ms.
 *
 * It stops as soon as a result is ready and returns how many bytes it took (0..len); the caller
 * then takes results with ctrlbus_decoder_next() until that returns CTRLBUS_RX_NONE, and feeds the
 * rest. While a result is waiting to be taken it takes no byte and returns 0. The usual loop:
 *
 *     while (len > 0) {
 *         size_t used = ctrlbus_decoder_feed(&dec, data, len, now_ms);
 *         data += used;
 *         len -= used;
 *         for (ctrlbus_rx_t rx; (rx = ctrlbus_decoder_next(&dec, &frame)) != CTRLBUS_RX_NONE;)
 *             handle(rx, &frame);
 *     }
 *
 * Feeding byte by byte or in chunks of any size gives the same results. A NULL data (or decoder)
 * feeds nothing and returns len, so that a caller's loop cannot spin on it. Not ISR-safe against
 * a concurrent ctrlbus_decoder_next() on the same decoder (feed it from one context; an interrupt
 * should put bytes in a ring instead).
 *
 * Cost, in byte visits of the buffer: a clean link costs O(1) per byte. Every failed candidate
 * restarts the scan at the byte after its flag over the bytes already buffered (backtracking), so
 * each byte is visited once per candidate whose span covers it, and a span is at most max_frame
 * bytes: amortised over a stream, at most about 2 x max_frame visits per input byte (the scan plus
 * moving the partial frame to the front of the buffer). The scan that follows one failure can visit
 * up to about max_frame^2 / 4 bytes when the failed span is full of nested false candidates, e.g.
 * 65536 visits for a 512-byte buffer; that work happens in the call that found the failure or in
 * the ctrlbus_decoder_next() calls after it. Nothing depends on history beyond the buffer.
 * Cost class: O(1) per byte on a clean link (a candidate's known remainder goes in as one copy and
 * its checksum is taken once, when it is complete). For one byte at a time, use
 * ctrlbus_decoder_push() rather than a feed of 1; ctrlbus_decoder_take() takes a chunk one result
 * per call and hands a whole frame out in place. */
size_t ctrlbus_decoder_feed(ctrlbus_decoder_t *decoder, const uint8_t *data, size_t len,
                            uint32_t now_ms);


/* Decodes the caller's bytes data[0..len) (passed as *data and *len) and returns the next result
 * in stream order, taking bytes as it needs them: *data and *len are advanced past the bytes taken.
 * This is the entry point for a chunk of received bytes (a DMA or ring buffer's, a host's read).
 * Returns CTRLBUS_RX_FRAME with *frame filled in (frame may be NULL), an event, or CTRLBUS_RX_NONE
 * once every byte has been taken and no result waits (*len is then 0). It is the same decoder as
 * the feed loop shown at ctrlbus_decoder_feed() (its results, counters and timeout, all bytes
 * stamped now_ms), in one call per result; any mix with push, feed, next and tick calls gives the
 * results that feeding those bytes would. The usual loop, for a chunk of received bytes:
 *
 *     for (ctrlbus_rx_t rx; (rx = ctrlbus_decoder_take(&dec, &data, &len, now_ms, &frame)) !=
 *                           CTRLBUS_RX_NONE;)
 *         handle(rx, &frame);
 *
 * A whole valid frame at the start of the bytes, with nothing buffered or waiting, is not copied:
 * its payload then points into the caller's bytes, so keep them unchanged until the frame has been
 * handled (a ring's slots must not be released to the writer before). Any other frame's payload
 * lies in the decoder's buffer, as with ctrlbus_decoder_next(). A NULL *data takes nothing and sets
 * *len to 0; a NULL decoder, data or len returns CTRLBUS_RX_NONE. Not ISR-safe (as
 * ctrlbus_decoder_feed()).
 *
 * Cost class: as ctrlbus_decoder_feed(); a whole frame handed out in place costs one pass over its
 * bytes (the checksum) and no copy, a frame's start one copy into the buffer. */
ctrlbus_rx_t ctrlbus_decoder_take(ctrlbus_decoder_t *decoder, const uint8_t **data, size_t *len,
                                  uint32_t now_ms, ctrlbus_frame_t *frame);

/* Takes one received byte (a UART interrupt's, or one from a ring) stamped with now_ms, and returns
 * the first result it completes: CTRLBUS_RX_NONE (the usual answer: the byte is inside a frame),
 * CTRLBUS_RX_FRAME with *frame filled in (frame may be NULL to skip it), or an event. It is the
 * same decoder as ctrlbus_decoder_feed() with len 1 followed by ctrlbus_decoder_next(): the same
 * rules, backtracking, inter-byte timeout (applied at now_ms before the byte) and counters, and
 * any mix of push, feed and tick calls gives the results that feeding those bytes would.
 *
 * After a result other than NONE, take the others with ctrlbus_decoder_next() until it returns
 * CTRLBUS_RX_NONE (backtracking can find several in bytes already buffered, and a timeout applied
 * before the byte comes out ahead of what the byte completes); the byte itself has been taken
 * either way. The usual loop:
 *
 *     for (ctrlbus_rx_t rx = ctrlbus_decoder_push(&dec, byte, now_ms, &frame);
 *          rx != CTRLBUS_RX_NONE; rx = ctrlbus_decoder_next(&dec, &frame))
 *         handle(rx, &frame);
 *
 * Pushing while results still wait takes nothing and returns CTRLBUS_RX_BUSY. A NULL decoder, or
 * a zeroed one never initialised by ctrlbus_decoder_init(), takes nothing and returns
 * CTRLBUS_RX_NONE. Not ISR-safe against other calls on the same decoder (as
 * ctrlbus_decoder_feed()): a receive interrupt may call it when it is the only context that
 * calls the decoder; otherwise it should put the bytes in a ring for the main loop.
 *
 * Cost class: O(1) for a byte inside a frame whose size is known (a comparison and a store); a
 * frame's last byte costs one pass over the frame (its checksum); a failure costs the rescan
 * described at ctrlbus_decoder_feed(). */
ctrlbus_rx_t ctrlbus_decoder_push(ctrlbus_decoder_t *decoder, uint8_t byte, uint32_t now_ms,
                                  ctrlbus_frame_t *frame);

/* Applies the inter-byte timeout at now_ms without new bytes (the same as feeding 0 bytes). Call it
 * from the main loop; then take results with ctrlbus_decoder_next(). A partial frame older than the
 * timeout (strictly more than timeout_ms since its last byte) fails as a timeout, and the bytes it
 * held are rescanned: complete frames among them are still yielded, partial ones are dropped.
 * Not ISR-safe (as ctrlbus_decoder_feed()). Cost: as ctrlbus_decoder_feed() with len 0. */
void ctrlbus_decoder_tick(ctrlbus_decoder_t *decoder, uint32_t now_ms);

/* Takes the next result in stream order. Returns CTRLBUS_RX_NONE when there is none (feed more
 * bytes or tick), CTRLBUS_RX_FRAME with *frame filled in (frame may be NULL to skip it), or an
 * event. The frame's payload stays valid until the next call on this decoder. Results that
 * backtracking finds in bytes already buffered come out of successive calls. Not ISR-safe (as
 * ctrlbus_decoder_feed()). Cost: O(1) to hand out a waiting result, otherwise the rescan work
 * described at ctrlbus_decoder_feed(). */
ctrlbus_rx_t ctrlbus_decoder_next(ctrlbus_decoder_t *decoder, ctrlbus_frame_t *frame);

/* True while the decoder holds received bytes it has not handed out: results still to be taken, or
 * (once ctrlbus_decoder_next() has returned CTRLBUS_RX_NONE) a partial frame that a later tick may
 * time out. ISR-safe. Cost: O(1). */
bool ctrlbus_decoder_busy(const ctrlbus_decoder_t *decoder);

/* The contract's name of a result: "frame", "garbage", "checksum_error", "oversize", "timeout",
 * "empty_frame", or "none" (and "busy" for CTRLBUS_RX_BUSY, which is not a result of the stream). Returns a string constant. ISR-safe. Cost: O(1). */
const char *ctrlbus_rx_name(ctrlbus_rx_t rx);

#ifdef __cplusplus
}
#endif

#endif
