/* SPDX-License-Identifier: MIT */
/* A tiny test harness: checks that report file:line and keep going, a runner, a summary.
 *
 *   static void test_something(void) { CHECK_EQ(1 + 1, 2); }
 *   int main(void) { RUN(test_something); return harness_finish(); }
 *
 * A failed check prints the expression, both values and the current context (set with
 * harness_context(), e.g. the name of the vector being run) and marks the test failed. */
#ifndef CTRLBUS_TEST_HARNESS_H
#define CTRLBUS_TEST_HARNESS_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#define CHECK(cond) harness_check((cond), __FILE__, __LINE__, #cond)
#define CHECK_EQ(actual, expected)                                                                 \
    harness_check_int((long long)(actual), (long long)(expected), __FILE__, __LINE__, #actual,     \
                      #expected)
#define CHECK_STR(actual, expected)                                                                \
    harness_check_str((actual), (expected), __FILE__, __LINE__, #actual)
#define CHECK_MEM(actual, actual_len, expected, expected_len)                                     \
    harness_check_mem((actual), (size_t)(actual_len), (expected), (size_t)(expected_len),          \
                      __FILE__, __LINE__, #actual)
#define RUN(test) harness_run(#test, test)

/* Each returns whether the check passed. */
bool harness_check(bool ok, const char *file, int line, const char *expr);
bool harness_check_int(long long actual, long long expected, const char *file, int line,
                       const char *actual_expr, const char *expected_expr);
bool harness_check_str(const char *actual, const char *expected, const char *file, int line,
                       const char *expr);
bool harness_check_mem(const void *actual, size_t actual_len, const void *expected,
                       size_t expected_len, const char *file, int line, const char *expr);

/* Sets the text printed with every failure until the next call (NULL or "" clears it). */
void harness_context(const char *format, ...);
/* Records a failure with a message of its own (for checks that need more than one line). */
void harness_fail(const char *file, int line, const char *format, ...);
/* Notes something that was not run (printed in the summary, not a failure). */
void harness_note(const char *format, ...);

void harness_run(const char *name, void (*test)(void));
/* Prints the summary; returns the process exit code (0 = every check passed). */
int harness_finish(void);

/* Parses hex text ("10 01 00 11", spaces optional) into out; returns the byte count. Aborts the
 * program on malformed text or more than cap bytes (a bug in the test itself). */
size_t harness_unhex(uint8_t *out, size_t cap, const char *text);

/* Hex text ("10 01 00 11") of len bytes into out (at least 3 * len + 1 bytes). */
void harness_hex(char *out, const uint8_t *data, size_t len);

#endif
