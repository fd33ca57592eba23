/* Differential-drive math; see diffdrive.h. */
#include "diffdrive.h"

#define Q16_ONE 65536.0f
#define DEGREES_PER_RADIAN 57.29577951308232f
/* Largest rotation done in one series step; the series below is good to 2e-6 there. */
#define MAX_SERIES_ANGLE_RAD 0.5f

static int32_t saturate_i64(int64_t value)
{
    if (value > INT32_MAX) {
        return INT32_MAX;
    }
    if (value < INT32_MIN) {
        return INT32_MIN;
    }
    return (int32_t)value;
}

/* value / 65536 rounded to nearest, halves away from zero. */
static int64_t q16_round(int64_t value)
{
    return value >= 0 ? (value + 32768) / 65536 : -((-value + 32768) / 65536);
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

void diffdrive_wheel_speeds(int32_t vx_mps_q16, int32_t omega_radps_q16, int32_t half_track_mm,
                            int32_t *left_mm_s, int32_t *right_mm_s)
{
    int64_t forward = (int64_t)vx_mps_q16 * 1000;
    int64_t turn = (int64_t)omega_radps_q16 * half_track_mm;
    *left_mm_s = saturate_i64(q16_round(forward - turn));
    *right_mm_s = saturate_i64(q16_round(forward + turn));
}

void diffdrive_pose_reset(diffdrive_pose_t *pose, float x_mm, float y_mm)
{
    pose->x_mm = x_mm;
    pose->y_mm = y_mm;
    pose->heading_cos = 1.0f;
    pose->heading_sin = 0.0f;
    pose->turned_rad = 0.0f;
}

/* Rotate the unit vector (*c, *s) by `angle` (|angle| <= MAX_SERIES_ANGLE_RAD), then pull it
 * back to unit length so that rounding does not build up over many steps. */
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

void diffdrive_pose_turn(diffdrive_pose_t *pose, float angle_rad)
{
    rotate(&pose->heading_cos, &pose->heading_sin, angle_rad);
    pose->turned_rad += angle_rad;
}

void diffdrive_pose_advance(diffdrive_pose_t *pose, float left_mm, float right_mm, float half_track_mm)
{
    float distance = (left_mm + right_mm) / 2.0f;
    float turn = (right_mm - left_mm) / (2.0f * half_track_mm);
    float half = turn / 2.0f;
    /* The chord of an arc is its length times sin(h)/h, along the heading halfway round. */
    float chord = distance;
    if (half > 1e-4f || half < -1e-4f) {
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
    diffdrive_pose_turn(pose, turn);
}

void diffdrive_take_deadreckon(diffdrive_pose_t *motion, int32_t *dx_mm_q16, int32_t *dy_mm_q16,
                               int32_t *dtheta_deg_q16)
{
    *dx_mm_q16 = float_to_q16(motion->x_mm);
    *dy_mm_q16 = float_to_q16(motion->y_mm);
    *dtheta_deg_q16 = float_to_q16(motion->turned_rad * DEGREES_PER_RADIAN);
    diffdrive_pose_reset(motion, 0.0f, 0.0f);
}
