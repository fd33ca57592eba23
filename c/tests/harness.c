/* SPDX-License-Identifier: MIT */
/* The test harness (see harness.h). Test code, so stdio and file-scope state are fine here. */
#include "harness.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static char context[256];
static const char *current_test = "";
static int checks;
static int failures;
static int failed_tests;
static int tests;
static int notes;

static void print_failure_header(const char *file, int line)
{
    fprintf(stderr, "FAIL %s (%s:%d)", current_test, file, line);
    if (context[0] != '\0') {
        fprintf(stderr, " [%s]", context);
    }
    fputs(": ", stderr);
}

bool harness_check(bool ok, const char *file, int line, const char *expr)
{
    checks++;
    if (!ok) {
        failures++;
        print_failure_header(file, line);
        fprintf(stderr, "%s\n", expr);
    }
    return ok;
}

bool harness_check_int(long long actual, long long expected, const char *file, int line,
                       const char *actual_expr, const char *expected_expr)
{
    checks++;
    if (actual != expected) {
        failures++;
        print_failure_header(file, line);
        fprintf(stderr, "%s == %lld, expected %s == %lld\n", actual_expr, actual, expected_expr,
                expected);
        return false;
    }
    return true;
}

bool harness_check_str(const char *actual, const char *expected, const char *file, int line,
                       const char *expr)
{
    checks++;
    bool ok = (actual == NULL && expected == NULL) ||
              (actual != NULL && expected != NULL && strcmp(actual, expected) == 0);
    if (!ok) {
        failures++;
        print_failure_header(file, line);
        fprintf(stderr, "%s == \"%s\", expected \"%s\"\n", expr, actual ? actual : "(null)",
                expected ? expected : "(null)");
    }
    return ok;
}

void harness_hex(char *out, const uint8_t *data, size_t len)
{
    out[0] = '\0';
    for (size_t i = 0; i < len; i++) {
        sprintf(out + 3 * i, i + 1 < len ? "%02X " : "%02X", data[i]);
    }
}

static int hex_digit(char c)
{
    if (c >= '0' && c <= '9') {
        return c - '0';
    }
    if (c >= 'a' && c <= 'f') {
        return c - 'a' + 10;
    }
    if (c >= 'A' && c <= 'F') {
        return c - 'A' + 10;
    }
    return -1;
}

size_t harness_unhex(uint8_t *out, size_t cap, const char *text)
{
    size_t len = 0;
    for (const char *p = text; *p != '\0';) {
        if (*p == ' ') {
            p++;
            continue;
        }
        int high = hex_digit(p[0]);
        int low = high < 0 ? -1 : hex_digit(p[1]);
        if (low < 0 || len == cap) {
            fprintf(stderr, "harness_unhex: bad or too long hex text \"%s\"\n", text);
            abort();
        }
        out[len++] = (uint8_t)(high * 16 + low);
        p += 2;
    }
    return len;
}

static void print_hex(const void *data, size_t len)
{
    const uint8_t *bytes = data;
    size_t shown = len > 64 ? 64 : len;
    for (size_t i = 0; i < shown; i++) {
        fprintf(stderr, i ? " %02X" : "%02X", bytes[i]);
    }
    if (shown < len) {
        fprintf(stderr, " ... (%zu bytes)", len);
    }
}

bool harness_check_mem(const void *actual, size_t actual_len, const void *expected,
                       size_t expected_len, const char *file, int line, const char *expr)
{
    checks++;
    bool ok = actual_len == expected_len &&
              (actual_len == 0 || memcmp(actual, expected, actual_len) == 0);
    if (!ok) {
        failures++;
        print_failure_header(file, line);
        fprintf(stderr, "%s\n    got      ", expr);
        print_hex(actual, actual_len);
        fputs("\n    expected ", stderr);
        print_hex(expected, expected_len);
        fputc('\n', stderr);
    }
    return ok;
}

void harness_context(const char *format, ...)
{
    context[0] = '\0';
    if (format == NULL) {
        return;
    }
    va_list args;
    va_start(args, format);
    vsnprintf(context, sizeof context, format, args);
    va_end(args);
}

void harness_fail(const char *file, int line, const char *format, ...)
{
    checks++;
    failures++;
    print_failure_header(file, line);
    va_list args;
    va_start(args, format);
    vfprintf(stderr, format, args);
    va_end(args);
    fputc('\n', stderr);
}

void harness_note(const char *format, ...)
{
    notes++;
    fputs("note: ", stdout);
    va_list args;
    va_start(args, format);
    vprintf(format, args);
    va_end(args);
    fputc('\n', stdout);
}

void harness_run(const char *name, void (*test)(void))
{
    int failures_before = failures;
    current_test = name;
    context[0] = '\0';
    tests++;
    test();
    context[0] = '\0';
    if (failures != failures_before) {
        failed_tests++;
    }
    printf("%s %s\n", failures != failures_before ? "FAIL" : "ok  ", name);
}

int harness_finish(void)
{
    printf("%d tests, %d checks, %d failed checks in %d tests, %d notes\n", tests, checks,
           failures, failed_tests, notes);
    return failures == 0 ? 0 : 1;
}
