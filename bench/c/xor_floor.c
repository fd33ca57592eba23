/* SPDX-License-Identifier: MIT */
/*
 * The floor of a byte API for our framing: the plainest per-byte state machine a base could write
 * (hunt for 0x10/0x50, read the length, take LEN bytes, compare the XOR), with no backtracking, no
 * inter-byte timeout and no error reporting beyond a count. It is a reference row for the C parser
 * benchmark, not a decoder: what any byte API for this framing costs at least.
 *
 *   xor_floor MODE FILE
 *
 * MODE
 *   baseline  read the file and walk its bytes without parsing (the cost subtracted)
 *   inline    the state machine's step inlined into the loop over the bytes
 *   call      one call of an out-of-line step per byte (as a UART interrupt calling a library)
 *
 * Prints "bytes=N frames=F bad=E" so the caller can check the parse was real.
 */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "read_file.h"

#define BUFFER 512u

typedef enum { HUNT, LEN_LO, LEN_HI, BODY } phase_t;

typedef struct {
    uint8_t buffer[BUFFER];
    uint32_t len;  /* bytes in buffer */
    uint32_t need; /* total frame size once the length is known */
    uint8_t phase;
    uint8_t checksum;
    unsigned long bad;
} floor_parser_t;

/* One byte; returns 1 when it completes a frame whose XOR is right. A byte inside a frame, the
 * common case, is tested first. */
static inline __attribute__((always_inline)) int floor_step(floor_parser_t *p, uint8_t byte)
{
    if (p->phase == BODY) {
        p->buffer[p->len++] = byte;
        p->checksum ^= byte;
        if (p->len != p->need) {
            return 0;
        }
        p->phase = HUNT;
        if (p->checksum != 0) {
            p->bad++;
            return 0;
        }
        return 1;
    }
    if (p->phase == HUNT) {
        if (byte == 0x10u || byte == 0x50u) {
            p->buffer[0] = byte;
            p->len = 1;
            p->checksum = byte;
            p->phase = LEN_LO;
        }
        return 0;
    }
    p->buffer[p->len++] = byte;
    p->checksum ^= byte;
    if (p->phase == LEN_LO && p->buffer[0] == 0x10u) {
        p->need = 3u + byte; /* flag, LEN, LEN bytes, checksum */
        p->phase = BODY;
    } else if (p->phase == LEN_LO) {
        p->phase = LEN_HI;
    } else {
        p->need = 4u + ((uint32_t)p->buffer[1] | (uint32_t)byte << 8);
        p->phase = p->need <= BUFFER ? BODY : HUNT;
    }
    return 0;
}

/* The same step behind a call, as a library function called per byte would be. */
static __attribute__((noinline)) int floor_step_call(floor_parser_t *p, uint8_t byte)
{
    return floor_step(p, byte);
}

static unsigned long walk_bytes(const unsigned char *data, size_t size)
{
    volatile unsigned char sink = 0;
    for (size_t i = 0; i < size; i++) {
        sink = data[i];
    }
    return (unsigned long)sink * 0u;
}

int main(int argc, char **argv)
{
    if (argc != 3) {
        fprintf(stderr, "usage: %s baseline|inline|call FILE\n", argv[0]);
        return 2;
    }
    size_t size = 0;
    unsigned char *data = read_file(argv[2], &size);
    if (data == NULL) {
        return 2;
    }
    static floor_parser_t parser;
    unsigned long frames = 0;
    if (strcmp(argv[1], "baseline") == 0) {
        frames = walk_bytes(data, size);
    } else if (strcmp(argv[1], "inline") == 0) {
        for (size_t i = 0; i < size; i++) {
            frames += (unsigned long)floor_step(&parser, data[i]);
        }
    } else if (strcmp(argv[1], "call") == 0) {
        for (size_t i = 0; i < size; i++) {
            frames += (unsigned long)floor_step_call(&parser, data[i]);
        }
    } else {
        fprintf(stderr, "unknown mode %s\n", argv[1]);
        free(data);
        return 2;
    }
    printf("bytes=%lu frames=%lu bad=%lu\n", (unsigned long)size, frames, parser.bad);
    free(data);
    return 0;
}
