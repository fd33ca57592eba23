/* SPDX-License-Identifier: MIT */
/*
 * Benchmark harness for the ctrlbus C stream decoder: feed a capture file to the decoder and count
 * the frames, so that callgrind can count the instructions it takes.
 *
 *   ctrlbus_parse MODE FILE
 *
 * MODE
 *   baseline  read the file and walk its bytes without decoding (the cost subtracted)
 *   bytes     ctrlbus_decoder_feed() one byte at a time, each followed by ctrlbus_decoder_next()
 *   push      ctrlbus_decoder_push() per byte, as a UART receive interrupt would: the byte API
 *   chunks    ctrlbus_decoder_take() on CHUNK bytes at a time until it returns CTRLBUS_RX_NONE, as a
 *             DMA or ring-buffer reader would (whole frames are handed out in place)
 *   feedchunks ctrlbus_decoder_feed() CHUNK bytes at a time (the feed-and-next loop)
 *
 * Each feed or push is followed by ctrlbus_decoder_next() until it returns CTRLBUS_RX_NONE (after a
 * push, only when the push returned a result), the loops the header documents. The decoder gets a 512-byte buffer (the reference base's receive buffer) and
 * the default inter-byte timeout; the time stays 0, so nothing times out.
 *
 * Prints "bytes=N frames=F events=E chunk=C" so the caller can check the decoding was real.
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "read_file.h"

#include "ctrlbus/frame.h"

#define DECODER_BUFFER 512u
#ifndef CHUNK
#define CHUNK 64u
#endif

/* The same walk over the bytes as the decoding loops, with the decoder replaced by a store the
 * compiler cannot drop. */
static unsigned long walk_bytes(const unsigned char *data, size_t size)
{
    volatile unsigned char sink = 0;
    for (size_t i = 0; i < size; i++) {
        sink = data[i];
    }
    return (unsigned long)sink * 0u;
}

typedef struct {
    unsigned long frames;
    unsigned long events;
} tally_t;

static void feed(ctrlbus_decoder_t *dec, const uint8_t *data, size_t len, tally_t *tally)
{
    while (len > 0) {
        size_t used = ctrlbus_decoder_feed(dec, data, len, 0u);
        data += used;
        len -= used;
        ctrlbus_frame_t frame;
        for (ctrlbus_rx_t rx; (rx = ctrlbus_decoder_next(dec, &frame)) != CTRLBUS_RX_NONE;) {
            if (rx == CTRLBUS_RX_FRAME) {
                tally->frames++;
            } else {
                tally->events++;
            }
        }
    }
}

static void tally_add(tally_t *tally, ctrlbus_rx_t rx)
{
    if (rx == CTRLBUS_RX_FRAME) {
        tally->frames++;
    } else {
        tally->events++;
    }
}

static void push_all(const unsigned char *data, size_t size, tally_t *tally)
{
    uint8_t buffer[DECODER_BUFFER];
    ctrlbus_decoder_t dec;
    if (ctrlbus_decoder_init(&dec, buffer, sizeof buffer, CTRLBUS_DEFAULT_TIMEOUT_MS, NULL) != CTRLBUS_OK) {
        fprintf(stderr, "ctrlbus_decoder_init failed\n");
        exit(2);
    }
    ctrlbus_frame_t frame;
    for (size_t i = 0; i < size; i++) {
        for (ctrlbus_rx_t rx = ctrlbus_decoder_push(&dec, data[i], 0u, &frame); rx != CTRLBUS_RX_NONE;
             rx = ctrlbus_decoder_next(&dec, &frame)) {
            tally_add(tally, rx);
        }
    }
}

static void take_all(const unsigned char *data, size_t size, size_t chunk, tally_t *tally)
{
    uint8_t buffer[DECODER_BUFFER];
    ctrlbus_decoder_t dec;
    if (ctrlbus_decoder_init(&dec, buffer, sizeof buffer, CTRLBUS_DEFAULT_TIMEOUT_MS, NULL) != CTRLBUS_OK) {
        fprintf(stderr, "ctrlbus_decoder_init failed\n");
        exit(2);
    }
    ctrlbus_frame_t frame;
    for (size_t pos = 0; pos < size; pos += chunk) {
        const uint8_t *bytes = data + pos;
        size_t len = size - pos < chunk ? size - pos : chunk;
        for (ctrlbus_rx_t rx; (rx = ctrlbus_decoder_take(&dec, &bytes, &len, 0u, &frame)) != CTRLBUS_RX_NONE;) {
            tally_add(tally, rx);
        }
    }
}

static void decode(const unsigned char *data, size_t size, size_t chunk, tally_t *tally)
{
    uint8_t buffer[DECODER_BUFFER];
    ctrlbus_decoder_t dec;
    if (ctrlbus_decoder_init(&dec, buffer, sizeof buffer, CTRLBUS_DEFAULT_TIMEOUT_MS, NULL) != CTRLBUS_OK) {
        fprintf(stderr, "ctrlbus_decoder_init failed\n");
        exit(2);
    }
    for (size_t pos = 0; pos < size; pos += chunk) {
        size_t len = size - pos < chunk ? size - pos : chunk;
        feed(&dec, data + pos, len, tally);
    }
}

int main(int argc, char **argv)
{
    if (argc != 3) {
        fprintf(stderr, "usage: %s baseline|bytes|push|chunks|feedchunks FILE\n", argv[0]);
        return 2;
    }
    size_t size = 0;
    unsigned char *data = read_file(argv[2], &size);
    if (data == NULL) {
        return 2;
    }
    tally_t tally = {0, 0};
    size_t chunk = 1;
    if (strcmp(argv[1], "baseline") == 0) {
        tally.frames = walk_bytes(data, size);
    } else if (strcmp(argv[1], "bytes") == 0) {
        decode(data, size, 1, &tally);
    } else if (strcmp(argv[1], "push") == 0) {
        push_all(data, size, &tally);
    } else if (strcmp(argv[1], "chunks") == 0) {
        chunk = CHUNK;
        take_all(data, size, chunk, &tally);
    } else if (strcmp(argv[1], "feedchunks") == 0) {
        chunk = CHUNK;
        decode(data, size, chunk, &tally);
    } else {
        fprintf(stderr, "unknown mode %s\n", argv[1]);
        free(data);
        return 2;
    }
    printf("bytes=%lu frames=%lu events=%lu chunk=%lu\n", (unsigned long)size, tally.frames, tally.events,
           (unsigned long)chunk);
    free(data);
    return 0;
}
