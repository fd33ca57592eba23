/* SPDX-License-Identifier: MIT */
/* Test support: messages as flat field lists (see msg_fields.h). */
#include "msg_fields.h"

#include <stdarg.h>
#include <stdio.h>
#include <string.h>

#include "answer_fields.h"
#include "harness.h"

static msg_field_t *add(msg_fields_t *out, vec_value_type_t type, const char *format, ...)
{
    static msg_field_t overflow; /* absorbs writes past the end; count still tells */
    msg_field_t *field = out->count < MSG_FIELDS_MAX ? &out->items[out->count] : &overflow;
    out->count++;
    memset(field, 0, sizeof *field);
    va_list args;
    va_start(args, format);
    vsnprintf(field->path, sizeof field->path, format, args);
    va_end(args);
    field->type = type;
    return field;
}

static void add_int(msg_fields_t *out, const char *path, long long value)
{
    add(out, VEC_INT, "%s", path)->integer = value;
}

static void add_int_at(msg_fields_t *out, const char *name, size_t index, long long value)
{
    add(out, VEC_INT, "%s[%zu]", name, index)->integer = value;
}

static void add_null(msg_fields_t *out, const char *path)
{
    add(out, VEC_NULL, "%s", path);
}

static void add_text(msg_fields_t *out, const char *path, const char *text)
{
    msg_field_t *field = add(out, VEC_TEXT, "%s", path);
    snprintf(field->text, sizeof field->text, "%s", text);
}

static void add_bytes(msg_fields_t *out, const char *path, const uint8_t *bytes, size_t len)
{
    msg_field_t *field = add(out, VEC_BYTES, "%s", path);
    field->bytes = bytes;
    field->len = len;
}

static void add_positions(msg_fields_t *out, const char *name, const ctrlbus_position_t *positions)
{
    for (size_t i = 0; i < CTRLBUS_CONF_SLOTS; i++) {
        add(out, VEC_INT, "%s[%zu].x_mm_q8", name, i)->integer = positions[i].x_mm_q8;
        add(out, VEC_INT, "%s[%zu].y_mm_q8", name, i)->integer = positions[i].y_mm_q8;
        add(out, VEC_INT, "%s[%zu].z_mm_q8", name, i)->integer = positions[i].z_mm_q8;
        add(out, VEC_INT, "%s[%zu].angle_deg_q8", name, i)->integer = positions[i].angle_deg_q8;
    }
}

void msg_fields_of_request(msg_fields_t *out, const ctrlbus_request_t *r)
{
    out->count = 0;
    switch (r->kind) {
    case CTRLBUS_REQ_SYNC: add_bytes(out, "filler", r->as.sync.filler, r->as.sync.filler_len); break;
    case CTRLBUS_REQ_ECHO: add_bytes(out, "data", r->as.echo.data, r->as.echo.data_len); break;
    case CTRLBUS_REQ_BASE_CMD: add_int(out, "subcommand", r->as.base_cmd.subcommand); break;
    case CTRLBUS_REQ_CONNECT_BASE:
        add_int(out, "protocol_version", r->as.connect_base.protocol_version);
        break;
    case CTRLBUS_REQ_GET_CHARGER_DATA:
        add_int(out, "data_type", r->as.get_charger_data.data_type);
        break;
    case CTRLBUS_REQ_SET_BASE_MOTOR:
        for (size_t i = 0; i < CTRLBUS_MOTOR_SPEEDS; i++) {
            add_int_at(out, "speeds_mm_s", i, r->as.set_base_motor.speeds_mm_s[i]);
        }
        break;
    case CTRLBUS_REQ_SET_V_AND_GET_DEADRECKON:
        add_int(out, "vx_mps_q16", r->as.set_v_and_get_deadreckon.vx_mps_q16);
        add_int(out, "vy_mps_q16", r->as.set_v_and_get_deadreckon.vy_mps_q16);
        add_int(out, "omega_radps_q16", r->as.set_v_and_get_deadreckon.omega_radps_q16);
        break;
    case CTRLBUS_REQ_SEND_EVENT: add_int(out, "event", r->as.send_event.event); break;
    case CTRLBUS_REQ_HEALTH_GET_ERROR: add_int(out, "index", r->as.health_get_error.index); break;
    case CTRLBUS_REQ_HEALTH_CLR_ERROR:
        add_int(out, "error_code", r->as.health_clr_error.error_code);
        break;
    default: break; /* no fields */
    }
}

/* One described answer field (answer_fields.h, generated from protocol/ctrlbus.json) as leaves. */
static void add_described(msg_fields_t *out, const uint8_t *answer, const answer_field_t *f)
{
    const uint8_t *at = answer + f->offset;
    if (f->has_at != ANSWER_FIELD_NONE && !*(const bool *)(const void *)(answer + f->has_at)) {
        add_null(out, f->name);
        return;
    }
    size_t count = f->count == 0u ? 1u : f->count;
    switch (f->kind) {
    case AF_TEXT: add_text(out, f->name, (const char *)at); return;
    case AF_BYTES: {
        const uint8_t *bytes = *(const uint8_t *const *)(const void *)at;
        if (f->count_at != ANSWER_FIELD_NONE) { /* counted bytes are a list of integers */
            for (size_t i = 0; i < answer[f->count_at]; i++) {
                add_int_at(out, f->name, i, bytes[i]);
            }
        } else {
            add_bytes(out, f->name, bytes, *(const size_t *)(const void *)(answer + f->len_at));
        }
        return;
    }
    case AF_POSITIONS: add_positions(out, f->name, (const ctrlbus_position_t *)(const void *)at); return;
    default: break;
    }
    for (size_t i = 0; i < count; i++) {
        long long value = f->kind == AF_U8    ? (long long)at[i]
                          : f->kind == AF_U16 ? (long long)((const uint16_t *)(const void *)at)[i]
                          : f->kind == AF_U32 ? (long long)((const uint32_t *)(const void *)at)[i]
                                              : (long long)((const int32_t *)(const void *)at)[i];
        if (f->count == 0u) {
            add_int(out, f->name, value);
        } else {
            add_int_at(out, f->name, i, value);
        }
    }
}

static void ok_fields(msg_fields_t *out, const ctrlbus_answer_t *a)
{
    if (a->to == CTRLBUS_REQ_POLL_BASE_CMD) { /* three forms, no layout */
        const ctrlbus_poll_base_cmd_answer_t *m = &a->as.poll_base_cmd;
        if (m->has_command) {
            add_int(out, "command", m->command);
        } else {
            add_null(out, "command");
        }
        add_int(out, "payload_size", m->payload_size);
        add_int(out, "pad", m->pad);
        return;
    }
    for (size_t k = 0; k < sizeof ANSWER_FIELDS / sizeof ANSWER_FIELDS[0]; k++) {
        if (ANSWER_FIELDS[k].to == a->to) {
            for (size_t i = 0; i < ANSWER_FIELDS[k].count; i++) {
                add_described(out, (const uint8_t *)&a->as, &ANSWER_FIELDS[k].fields[i]);
            }
        }
    }
}

void msg_fields_of_answer(msg_fields_t *out, const ctrlbus_answer_t *a)
{
    out->count = 0;
    switch (a->kind) {
    case CTRLBUS_ANSWER_OK: ok_fields(out, a); break;
    case CTRLBUS_ANSWER_ERROR: add_int(out, "error_code", a->as.error.error_code); break;
    case CTRLBUS_ANSWER_SYNC: add_bytes(out, "filler", a->as.sync.filler, a->as.sync.filler_len); break;
    case CTRLBUS_ANSWER_ECHO: add_bytes(out, "data", a->as.echo.data, a->as.echo.data_len); break;
    default: break; /* INVALID */
    }
}

static const msg_field_t *find(const msg_fields_t *list, const char *path)
{
    for (size_t i = 0; i < list->count && i < MSG_FIELDS_MAX; i++) {
        if (strcmp(list->items[i].path, path) == 0) {
            return &list->items[i];
        }
    }
    return NULL;
}

static bool same_value(const msg_field_t *a, vec_value_type_t type, long long integer,
                       const char *text, const uint8_t *bytes, size_t len)
{
    if (a->type != type) {
        return false;
    }
    switch (type) {
    case VEC_INT: return a->integer == integer;
    case VEC_TEXT: return strcmp(a->text, text) == 0;
    case VEC_BYTES: return a->len == len && (len == 0 || memcmp(a->bytes, bytes, len) == 0);
    default: return true;
    }
}

bool msg_fields_equal(const msg_fields_t *a, const msg_fields_t *b)
{
    if (a->count != b->count || a->count > MSG_FIELDS_MAX) {
        return false;
    }
    for (size_t i = 0; i < a->count; i++) {
        const msg_field_t *x = &a->items[i];
        const msg_field_t *y = find(b, x->path);
        if (y == NULL || !same_value(y, x->type, x->integer, x->text, x->bytes, x->len)) {
            return false;
        }
    }
    return true;
}

static void describe(char *out, size_t size, vec_value_type_t type, long long integer,
                     const char *text, const uint8_t *bytes, size_t len)
{
    switch (type) {
    case VEC_INT: snprintf(out, size, "%lld", integer); break;
    case VEC_NULL: snprintf(out, size, "null"); break;
    case VEC_TEXT: snprintf(out, size, "\"%s\"", text); break;
    default: {
        char hex[3 * 24 + 1];
        harness_hex(hex, bytes, len > 24 ? 24 : len);
        snprintf(out, size, "hex[%zu] %s%s", len, hex, len > 24 ? " ..." : "");
    }
    }
}

bool msg_fields_check(const msg_fields_t *actual, const vec_field_t *expected, size_t count,
                      const char *file, int line)
{
    bool ok = true;
    char want[128];
    char got[128];
    if (actual->count > MSG_FIELDS_MAX) {
        harness_fail(file, line, "too many fields to compare");
        return false;
    }
    for (size_t i = 0; i < count; i++) {
        const vec_field_t *e = &expected[i];
        const msg_field_t *a = find(actual, e->path);
        describe(want, sizeof want, e->type, e->integer, e->text, e->bytes.data, e->bytes.len);
        if (a == NULL) {
            harness_fail(file, line, "field %s: missing (expected %s)", e->path, want);
            ok = false;
        } else if (!same_value(a, e->type, e->integer, e->text, e->bytes.data, e->bytes.len)) {
            describe(got, sizeof got, a->type, a->integer, a->text, a->bytes, a->len);
            harness_fail(file, line, "field %s: got %s, expected %s", e->path, got, want);
            ok = false;
        }
    }
    for (size_t i = 0; i < actual->count; i++) {
        bool listed = false;
        for (size_t k = 0; k < count && !listed; k++) {
            listed = strcmp(expected[k].path, actual->items[i].path) == 0;
        }
        if (!listed) {
            const msg_field_t *a = &actual->items[i];
            describe(got, sizeof got, a->type, a->integer, a->text, a->bytes, a->len);
            harness_fail(file, line, "field %s: decoded (%s) but not in the vector", a->path, got);
            ok = false;
        }
    }
    return ok;
}
