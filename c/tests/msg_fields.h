/* SPDX-License-Identifier: MIT */
/* Test support: a decoded message as a flat list of (path, value) leaves, named exactly like the
 * contract's `fields` ("serial[1]", "sensors[0].x_mm_q8", null for absent optional fields), so a
 * message can be compared with a vector's fields or with another message. */
#ifndef CTRLBUS_TEST_MSG_FIELDS_H
#define CTRLBUS_TEST_MSG_FIELDS_H

#include <stdbool.h>
#include <stddef.h>

#include "ctrlbus/messages.h"
#include "vector_types.h"

#define MSG_FIELDS_MAX 160u

typedef struct {
    char path[48];
    vec_value_type_t type;
    long long integer;
    char text[40];
    const uint8_t *bytes;
    size_t len;
} msg_field_t;

typedef struct {
    msg_field_t items[MSG_FIELDS_MAX];
    size_t count;
} msg_fields_t;

void msg_fields_of_request(msg_fields_t *out, const ctrlbus_request_t *request);
void msg_fields_of_answer(msg_fields_t *out, const ctrlbus_answer_t *answer);

/* Whether two lists hold the same leaves (in any order). */
bool msg_fields_equal(const msg_fields_t *a, const msg_fields_t *b);

/* Compares a message's leaves with a vector's fields; records a failure per difference (missing,
 * extra, or different leaves), with file/line of the caller. Returns whether they match. */
bool msg_fields_check(const msg_fields_t *actual, const vec_field_t *expected, size_t count,
                      const char *file, int line);

#endif
