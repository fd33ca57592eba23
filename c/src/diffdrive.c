/* SPDX-License-Identifier: MIT */
/* Differential-drive helpers (see ctrlbus/diffdrive.h). */
#include "ctrlbus/diffdrive.h"

#include <stddef.h>

#define Q16_ONE 65536.0f
#define DEGREES_PER_RADIAN 57.29577951308232f
/* Largest rotation done in one series step; the series below is good to 2e-6 there. */
#define MAX_SERIES_ANGLE_RAD 0.5f
/* Below this half-turn (radians) the chord factor sin(h)/h comes from its series. */
#define SMALL_HALF_TURN_RAD 1e-4f

/* floor(x * factor / 2^17), in 32-bit arithmetic only (|x * factor| < 2^47): a 64-bit product
 * would pull in libgcc's multiply (90 bytes on a Cortex-M0). The remainder, x * factor mod 2^17,
 * needs no work here: it is the low 17 bits of the product taken modulo 2^32. */
static int32_t product_over_2_17(int32_t x, uint16_t factor)
{
    uint32_t x_low = (uint32_t)x & 0xFFFFu;
    int32_t x_high = (x - (int32_t)x_low) / 65536; /* exact: floor(x / 2^16), in -2^15..2^15-1 */
    uint32_t low_product = x_low * factor;         /* < 2^32 */
    /* floor(x * factor / 2^16), |sum| < 2^31 - 2^15 */
    int32_t sum = x_high * (int32_t)factor + (int32_t)(low_product >> 16);
    return (sum - (int32_t)((uint32_t)sum & 1u)) / 2; /* exact */
}

/* x * factor mod 2^17 (0..2^17-1): the product's low bits, exact in modular arithmetic. */
static int32_t product_rest(int32_t x, uint16_t factor)
{
    return (int32_t)(((uint32_t)x * factor) & 0x1FFFFu);
}

static int32_t float_to_q16(float value)
{
    float scaled = value * Q16_ONE;
    if (scaled >= 2147483647.0f) {
        return INT32_MAX;
    }
    if (scaled <= -2147483648.0f) {
        return INT32_MIN;
    }
    return (int32_t)(scaled >= 0.0f ? scaled + 0.5f : scaled - 0.5f);
}

void ctrlbus_diffdrive_wheel_speeds(int32_t vx_mps_q16, int32_t omega_radps_q16,
                                    uint16_t wheel_track_mm, int32_t *left_mm_s,
                                    int32_t *right_mm_s)
{
    /* Everything doubled (so W/2 stays exact) and in Q16, each product split at bit 17:
     * 2000 vx = forward * 2^17 + forward_rest, omega W = turn * 2^17 + turn_rest. */
    int32_t forward = product_over_2_17(vx_mps_q16, 2000);
    int32_t forward_rest = product_rest(vx_mps_q16, 2000);
    int32_t turn = product_over_2_17(omega_radps_q16, wheel_track_mm);
    int32_t turn_rest = product_rest(omega_radps_q16, wheel_track_mm);
    /* Left first (forward - turn), then right; one loop keeps one copy of the code. */
    turn = -turn;
    turn_rest = -turn_rest;
    int32_t *wheel = left_mm_s;
    for (int side = 0; side < 2; side++) {
        /* The speed times 2^17 is whole * 2^17 + rest, rest in (-2^17, 2^18); |whole| < 2^30. */
        int32_t whole = forward + turn;
        /* Rounded half up: floor((speed * 2^17 + 2^16) / 2^17); 2^17 more keeps rest positive. */
        uint32_t rest = (uint32_t)(forward_rest + turn_rest + 0x10000 + 0x20000);
        whole += (int32_t)(rest >> 17) - 1;
        /* A negative half (rounded up to whole exactly, whole <= 0) goes away from zero. */
        if ((rest & 0x1FFFFu) == 0u && whole <= 0) {
            whole--;
        }
        if (wheel != NULL) {
            *wheel = whole;
        }
        turn = -turn;
        turn_rest = -turn_rest;
        wheel = right_mm_s;
    }
}

void ctrlbus_diffdrive_pose_reset(ctrlbus_diffdrive_pose_t *pose, float x_mm, float y_mm)
{
    pose->x_mm = x_mm;
    pose->y_mm = y_mm;
    pose->heading_cos = 1.0f;
    pose->heading_sin = 0.0f;
    pose->turned_rad = 0.0f;
}

/* Rotates the unit vector (*c, *s) by angle (|angle| <= MAX_SERIES_ANGLE_RAD), then pulls it back
 * to unit length so that rounding does not build up over many steps. */
static void rotate_small(float *c, float *s, float angle)
{
    float a2 = angle * angle;
    float cos_a = 1.0f - a2 / 2.0f * (1.0f - a2 / 12.0f * (1.0f - a2 / 30.0f));
    float sin_a = angle * (1.0f - a2 / 6.0f * (1.0f - a2 / 20.0f * (1.0f - a2 / 42.0f)));
    float rc = *c * cos_a - *s * sin_a;
    float rs = *s * cos_a + *c * sin_a;
    /* One Newton step towards 1 / |v|: enough, as |v| is within 1e-6 of 1 here. */
    float scale = 1.5f - 0.5f * (rc * rc + rs * rs);
    *c = rc * scale;
    *s = rs * scale;
}

static void rotate(float *c, float *s, float angle)
{
    while (angle > MAX_SERIES_ANGLE_RAD) {
        rotate_small(c, s, MAX_SERIES_ANGLE_RAD);
        angle -= MAX_SERIES_ANGLE_RAD;
    }
    while (angle < -MAX_SERIES_ANGLE_RAD) {
        rotate_small(c, s, -MAX_SERIES_ANGLE_RAD);
        angle += MAX_SERIES_ANGLE_RAD;
    }
    rotate_small(c, s, angle);
}

void ctrlbus_diffdrive_pose_turn(ctrlbus_diffdrive_pose_t *pose, float angle_rad)
{
    rotate(&pose->heading_cos, &pose->heading_sin, angle_rad);
    pose->turned_rad += angle_rad;
}

void ctrlbus_diffdrive_pose_advance(ctrlbus_diffdrive_pose_t *pose, float left_mm, float right_mm,
                                    float wheel_track_mm)
{
    float distance = (left_mm + right_mm) / 2.0f;
    float turn = (right_mm - left_mm) / wheel_track_mm;
    float half = turn / 2.0f;
    /* The chord of an arc is its length times sin(h)/h, along the heading halfway round. */
    float chord;
    if (half > SMALL_HALF_TURN_RAD || half < -SMALL_HALF_TURN_RAD) {
        float c = 1.0f;
        float s = 0.0f;
        rotate(&c, &s, half);
        chord = distance * s / half;
    } else {
        chord = distance * (1.0f - half * half / 6.0f);
    }
    float mid_cos = pose->heading_cos;
    float mid_sin = pose->heading_sin;
    rotate(&mid_cos, &mid_sin, half);
    pose->x_mm += chord * mid_cos;
    pose->y_mm += chord * mid_sin;
    ctrlbus_diffdrive_pose_turn(pose, turn);
}

void ctrlbus_diffdrive_take_deadreckon(ctrlbus_diffdrive_pose_t *motion, int32_t *dx_mm_q16,
                                       int32_t *dy_mm_q16, int32_t *dtheta_deg_q16)
{
    int32_t dx = float_to_q16(motion->x_mm);
    int32_t dy = float_to_q16(motion->y_mm);
    int32_t dtheta = float_to_q16(motion->turned_rad * DEGREES_PER_RADIAN);
    if (dx_mm_q16 != NULL) {
        *dx_mm_q16 = dx;
    }
    if (dy_mm_q16 != NULL) {
        *dy_mm_q16 = dy;
    }
    if (dtheta_deg_q16 != NULL) {
        *dtheta_deg_q16 = dtheta;
    }
    /* What was not reported, as seen from the reported pose. The reported heading differs from
     * the true one by a rounding remainder, so rotating by the true heading is exact to second
     * order in that remainder. */
    float rest_x = motion->x_mm - (float)dx / Q16_ONE;
    float rest_y = motion->y_mm - (float)dy / Q16_ONE;
    float rest_turn = motion->turned_rad - (float)dtheta / Q16_ONE / DEGREES_PER_RADIAN;
    float c = motion->heading_cos;
    float s = motion->heading_sin;
    ctrlbus_diffdrive_pose_reset(motion, c * rest_x + s * rest_y, c * rest_y - s * rest_x);
    ctrlbus_diffdrive_pose_turn(motion, rest_turn);
}
