/* SPDX-License-Identifier: MIT */
/* Shared support of the ctrlbus fuzz targets (see README.md in this directory).
 *
 * Every target is a libFuzzer entry point, LLVMFuzzerTestOneInput(), that never returns an error:
 * a broken invariant aborts with a message (FUZZ_CHECK), which libFuzzer reports as a crash and
 * saves the input that caused it. The same sources build with any compiler as "replay" programs
 * (replay_main.c) that run saved inputs, so seeds and reproducers are regression tests in ctest. */
#ifndef CTRLBUS_FUZZ_COMMON_H
#define CTRLBUS_FUZZ_COMMON_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ctrlbus/frame.h"

/* The entry point every target defines. */
int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size);

/* Aborts with file, line and the failed condition when cond is false. */
#define FUZZ_CHECK(cond)                                                                           \
    do {                                                                                           \
        if (!(cond)) {                                                                             \
            fuzz_fail(__FILE__, __LINE__, #cond);                                                  \
        }                                                                                          \
    } while (0)

void fuzz_fail(const char *file, int line, const char *what);

/* The input, read front to back. Reading past its end gives zeros (and `left` stays 0), so a
 * short input is still a valid one. */
typedef struct {
    const uint8_t *data;
    size_t left;
} fuzz_input_t;

uint8_t fuzz_u8(fuzz_input_t *in);
uint16_t fuzz_u16(fuzz_input_t *in);

/* A small deterministic generator (xorshift32), seeded from the input, for the choices that
 * should not take bytes away from the stream itself (chunk sizes, time steps). */
typedef struct {
    uint32_t state;
} fuzz_rng_t;

void fuzz_rng_seed(fuzz_rng_t *rng, uint32_t seed);
uint32_t fuzz_rng(fuzz_rng_t *rng);
uint32_t fuzz_rng_below(fuzz_rng_t *rng, uint32_t n); /* 0..n-1; n > 0 */

/* A caller's buffer with guard regions on both sides: the library gets buffer[0..size) and must
 * never touch the guards. Under AddressSanitizer the guards are poisoned, so any access is caught
 * at once; otherwise fuzz_guarded_check() finds writes by their pattern. The storage is part of the
 * struct (make it static: no allocation per run), room for the largest frame buffer. */
#define FUZZ_GUARD 64u

typedef struct {
    uint8_t block[FUZZ_GUARD + CTRLBUS_FRAME_MAX + FUZZ_GUARD];
    uint8_t *buffer; /* block + FUZZ_GUARD */
    size_t size;
} fuzz_guarded_t;

void fuzz_guarded_init(fuzz_guarded_t *g, size_t size); /* size <= CTRLBUS_FRAME_MAX */
void fuzz_guarded_check(const fuzz_guarded_t *g);

/* Checks a frame that a decoder over buffer[0..max_frame) handed out: its bytes lie inside the
 * buffer, their XOR (checksum included) is 0, the flag and LEN match is_long and payload_len, it
 * has a command and it fits max_frame. */
void fuzz_check_frame(const ctrlbus_frame_t *frame, const uint8_t *buffer, size_t max_frame);

/* The counters' own consistency: every failed candidate is a resync. */
void fuzz_check_stats(const ctrlbus_decoder_stats_t *stats);

/* A compact record of a decoder's results, to compare two runs of the same stream. */
#define FUZZ_LOG_MAX (1u << 15)

typedef struct {
    uint32_t count;
    bool overflow;
    uint32_t entries[FUZZ_LOG_MAX]; /* rx, is_long, cmd, payload length and a payload hash */
} fuzz_log_t;

void fuzz_log_clear(fuzz_log_t *log);
void fuzz_log_add(fuzz_log_t *log, ctrlbus_rx_t rx, const ctrlbus_frame_t *frame);
bool fuzz_log_equal(const fuzz_log_t *a, const fuzz_log_t *b);

#endif
