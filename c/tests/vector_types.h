/* SPDX-License-Identifier: MIT */
/* The shapes of the shared test vectors as the generated ctrlbus_vectors.h holds them
 * (gen_vectors.py writes that header from the JSON files in vectors/; see vectors/README.md for
 * the meaning of every item). Arrays that the JSON leaves out or empty are NULL with a count of 0. */
#ifndef CTRLBUS_VECTOR_TYPES_H
#define CTRLBUS_VECTOR_TYPES_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

typedef struct {
    const uint8_t *data;
    size_t len;
} vec_bytes_t;

/* One leaf of a message's `fields`, flattened: "serial[1]", "sensors[0].x_mm_q8", "model". */
typedef enum { VEC_INT, VEC_NULL, VEC_TEXT, VEC_BYTES } vec_value_type_t;

typedef struct {
    const char *path;
    vec_value_type_t type;
    long long integer; /* VEC_INT */
    const char *text;  /* VEC_TEXT */
    vec_bytes_t bytes; /* VEC_BYTES: the hex fields (filler, data, blob) */
} vec_field_t;

typedef struct {
    bool is_long;
    uint8_t cmd;
    vec_bytes_t payload;
} vec_expected_frame_t;

typedef struct {
    const char *name; /* frames, bytes_discarded, checksum_errors, ... */
    long long value;
} vec_counter_t;

typedef struct {
    const vec_expected_frame_t *frames;
    size_t frame_count;
    bool events_given; /* streams may leave the events out: then they are not checked */
    const char *const *events;
    size_t event_count;
    const vec_counter_t *counters;
    size_t counter_count;
} vec_expect_t;

/* frames.json */
typedef struct {
    const char *name;
    vec_bytes_t wire;
    bool is_long;
    uint8_t cmd;
    vec_bytes_t payload;
    const char *kind;         /* "request" / "answer", NULL when the vector has no message */
    const char *message_name; /* request name, or OK/ERROR/INVALID/SYNC/ECHO */
    const char *to;           /* answers: the request answered */
    const vec_field_t *fields;
    size_t field_count;
} vec_frame_t;

/* invalid.json, frame_level */
typedef struct {
    const char *name;
    vec_bytes_t input;
    uint32_t timeout_ms; /* 0: timeout off */
    uint32_t max_frame;
    vec_expect_t expect;
    bool has_base_answer;
    vec_bytes_t base_answer;
} vec_frame_level_t;

/* invalid.json, message_level */
typedef struct {
    const char *name;
    const char *direction; /* "request" / "answer" */
    const char *to;        /* answers */
    bool is_long;
    uint8_t cmd;
    vec_bytes_t payload;
    const char *expect_error; /* "format" / "unsupported" */
    bool has_base_answer;
    vec_bytes_t base_answer;
} vec_message_level_t;

/* streams.json */
typedef struct {
    uint32_t t_ms;
    vec_bytes_t data;
} vec_chunk_t;

typedef struct {
    const char *name;
    uint32_t max_frame;
    uint32_t timeout_ms; /* 0: timeout off */
    const vec_chunk_t *chunks;
    size_t chunk_count;
    bool has_final_idle;
    uint32_t final_idle_ms;
    vec_expect_t expect;
} vec_stream_t;

#endif
