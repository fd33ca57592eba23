/* SPDX-License-Identifier: MIT */
/* Unit tests of the differential-drive helpers (ctrlbus/diffdrive.h). */
#include <stdint.h>
#include <stdio.h>

#include "ctrlbus/diffdrive.h"
#include "harness.h"

#define Q16 65536.0
#define PI 3.14159265358979323846
#define CHECK_NEAR(actual, expected, tolerance)                                                    \
    check_near((double)(actual), (double)(expected), (double)(tolerance), __FILE__, __LINE__,      \
               #actual)

static bool check_near(double actual, double expected, double tolerance, const char *file,
                       int line, const char *expr)
{
    double difference = actual > expected ? actual - expected : expected - actual;
    if (difference > tolerance) {
        harness_fail(file, line, "%s == %.6f, expected %.6f +- %g", expr, actual, expected,
                     tolerance);
        return false;
    }
    return harness_check(true, file, line, expr);
}

static void test_wheel_speeds(void)
{
    int32_t left = 0;
    int32_t right = 0;
    /* The reference's example command: vx 0.2 m/s, omega 0.5 rad/s, wheel track 236 mm (v4). */
    ctrlbus_diffdrive_wheel_speeds(13107, 32768, 236, &left, &right);
    CHECK_EQ(left, 141);
    CHECK_EQ(right, 259);
    ctrlbus_diffdrive_wheel_speeds(-13107, -32768, 236, &left, &right);
    CHECK_EQ(left, -141);
    CHECK_EQ(right, -259);
    /* Turning on the spot, wheel track 160 mm (SDP Mini): 1 rad/s -> 80 mm/s per wheel. */
    ctrlbus_diffdrive_wheel_speeds(0, 65536, 160, &left, &right);
    CHECK_EQ(left, -80);
    CHECK_EQ(right, 80);
    /* An odd track keeps its half millimetre: 1 rad/s on 161 mm is 80.5 mm/s, rounded away
     * from zero on both wheels. */
    ctrlbus_diffdrive_wheel_speeds(0, 65536, 161, &left, &right);
    CHECK_EQ(left, -81);
    CHECK_EQ(right, 81);
    /* The extremes fit: (2000 vx -+ 65535 omega) / 2^17, rounded, is below 2^31. */
    ctrlbus_diffdrive_wheel_speeds(INT32_MAX, INT32_MAX, UINT16_MAX, &left, &right);
    CHECK_EQ(left, -1040957440);
    CHECK_EQ(right, 1106493439); /* 1106493439.48 */
    ctrlbus_diffdrive_wheel_speeds(INT32_MIN, INT32_MIN, UINT16_MAX, &left, &right);
    CHECK_EQ(left, 1040957440);
    CHECK_EQ(right, -1106493440);
    /* Halves round away from zero: vx 4096 (1/16 m/s) is 62.5 mm/s on both wheels ... */
    ctrlbus_diffdrive_wheel_speeds(4096, 0, 236, &left, &right);
    CHECK(left == 63 && right == 63);
    ctrlbus_diffdrive_wheel_speeds(-4096, 0, 236, &left, &right);
    CHECK(left == -63 && right == -63);
    /* ... and omega W / 2 of 0.5 mm/s (omega 2 / 65536, W 32768) is 1 mm/s either way. */
    ctrlbus_diffdrive_wheel_speeds(0, 2, 32768, &left, &right);
    CHECK(left == -1 && right == 1);
    ctrlbus_diffdrive_wheel_speeds(0, 1, 32768, &left, &right); /* 0.25: rounds to 0 */
    CHECK(left == 0 && right == 0);
    /* NULL outputs are skipped. */
    ctrlbus_diffdrive_wheel_speeds(65536, 0, 236, NULL, &right);
    CHECK_EQ(right, 1000);
}

/* ---- the wheel speeds against the original 64-bit formula ----------------------------------- */

/* The wheel speeds as first written (64-bit products, then a rounded division), kept as the
 * reference model: the 32-bit arithmetic must give exactly the same value for every input. */
static int32_t reference_wheel_speed(int32_t vx_mps_q16, int32_t omega_radps_q16,
                                     uint16_t wheel_track_mm, int side)
{
    int64_t doubled = (int64_t)vx_mps_q16 * 2000 + side * ((int64_t)omega_radps_q16 * wheel_track_mm);
    int64_t divisor = 2 * 65536;
    int64_t rounded = doubled >= 0 ? (doubled + divisor / 2) / divisor
                                   : -((-doubled + divisor / 2) / divisor);
    CHECK(rounded >= INT32_MIN && rounded <= INT32_MAX); /* never saturates on a u16 track */
    return (int32_t)rounded;
}

static uint32_t xorshift32(uint32_t *state)
{
    uint32_t x = *state;
    x ^= x << 13;
    x ^= x >> 17;
    x ^= x << 5;
    *state = x;
    return x;
}

static long wheel_speed_mismatches;

static void compare_wheel_speeds(int32_t vx, int32_t omega, uint16_t track)
{
    int32_t left = 0;
    int32_t right = 0;
    ctrlbus_diffdrive_wheel_speeds(vx, omega, track, &left, &right);
    int32_t expected_left = reference_wheel_speed(vx, omega, track, -1);
    int32_t expected_right = reference_wheel_speed(vx, omega, track, 1);
    if (left != expected_left || right != expected_right) {
        if (wheel_speed_mismatches++ < 5) {
            harness_fail(__FILE__, __LINE__,
                         "wheel speeds (%ld, %ld, %u) = (%ld, %ld), expected (%ld, %ld)",
                         (long)vx, (long)omega, (unsigned)track, (long)left, (long)right,
                         (long)expected_left, (long)expected_right);
        }
    }
}

/* Values where the splitting at bits 16 and 17 and the rounding can go wrong. */
static const int32_t edge_values[] = {
    0,          1,          -1,         2,           -2,          32767,      -32768,
    32768,      -32769,     65535,      -65535,      65536,       -65536,     65537,
    -65537,     98304,      -98304,     131071,      -131071,     131072,     -131072,
    196608,     -196608,    0x7FFF0000, -0x7FFF0000, 0x7FFFFFFF,  INT32_MIN,  INT32_MIN + 1,
    0x40000000, -0x40000000, 0x3FFFFFFF, 1000000000, -1000000000, 26214,      13107};

static void test_wheel_speeds_match_reference(void)
{
    const size_t edges = sizeof edge_values / sizeof edge_values[0];
    const uint16_t tracks[] = {0, 1, 2, 3, 160, 161, 236, 32767, 32768, 65534, 65535};
    const size_t track_count = sizeof tracks / sizeof tracks[0];
    /* Every pair of edge values on the edge tracks, and on every track for some pairs. */
    for (size_t i = 0; i < edges; i++) {
        for (size_t j = 0; j < edges; j++) {
            for (size_t k = 0; k < track_count; k++) {
                compare_wheel_speeds(edge_values[i], edge_values[j], tracks[k]);
            }
        }
    }
    for (uint32_t track = 0; track <= UINT16_MAX; track++) {
        compare_wheel_speeds(INT32_MAX, INT32_MIN, (uint16_t)track);
        compare_wheel_speeds(-1, 1, (uint16_t)track);
        compare_wheel_speeds(33, -65535, (uint16_t)track);
    }
    /* Every remainder below 2^17 for vx (the rounding of 2000 vx / 2^17 cycles with period
     * 2^16) against a few turns, then random inputs: uniform, small, and near the edges. */
    uint32_t state = 0x2545F491u;
    for (int32_t vx = -70000; vx <= 70000; vx++) {
        compare_wheel_speeds(vx, (int32_t)(xorshift32(&state) >> 14) - 131072,
                             (uint16_t)xorshift32(&state));
    }
    for (int n = 0; n < 1000000; n++) {
        uint32_t kind = xorshift32(&state) % 3u;
        int32_t vx = (int32_t)xorshift32(&state);
        int32_t omega = (int32_t)xorshift32(&state);
        if (kind == 1u) {
            vx = (int32_t)(xorshift32(&state) % 400001u) - 200000;
            omega = (int32_t)(xorshift32(&state) % 400001u) - 200000;
        } else if (kind == 2u) {
            vx = edge_values[xorshift32(&state) % edges] ^ (int32_t)(xorshift32(&state) & 7u);
            omega = edge_values[xorshift32(&state) % edges] ^ (int32_t)(xorshift32(&state) & 7u);
        }
        compare_wheel_speeds(vx, omega, (uint16_t)xorshift32(&state));
    }
    CHECK_EQ(wheel_speed_mismatches, 0);
}

static void test_straight_and_turns(void)
{
    ctrlbus_diffdrive_pose_t pose;
    int32_t dx = 0;
    int32_t dy = 0;
    int32_t dtheta = 0;

    ctrlbus_diffdrive_pose_reset(&pose, 0.0f, 0.0f);
    ctrlbus_diffdrive_pose_advance(&pose, 1000.0f, 1000.0f, 236.0f);
    ctrlbus_diffdrive_take_deadreckon(&pose, &dx, &dy, &dtheta);
    CHECK_EQ(dx, 1000 * 65536);
    CHECK_EQ(dy, 0);
    CHECK_EQ(dtheta, 0);
    /* Taking restarts: nothing moved since, so nothing is reported. */
    ctrlbus_diffdrive_take_deadreckon(&pose, &dx, &dy, &dtheta);
    CHECK(dx == 0 && dy == 0 && dtheta == 0);

    /* A quarter turn on the spot, then 100 mm: the motion is along +y of the starting frame. */
    float quarter = (float)(PI / 2.0 * 118.0);
    ctrlbus_diffdrive_pose_advance(&pose, -quarter, quarter, 236.0f);
    ctrlbus_diffdrive_pose_advance(&pose, 100.0f, 100.0f, 236.0f);
    ctrlbus_diffdrive_take_deadreckon(&pose, &dx, &dy, &dtheta);
    CHECK_NEAR(dx / Q16, 0.0, 0.01);
    CHECK_NEAR(dy / Q16, 100.0, 0.01);
    CHECK_NEAR(dtheta / Q16, 90.0, 0.001);

    /* Clockwise is negative, and a full turn is 360 degrees, not 0. */
    float full = (float)(2.0 * PI * 118.0);
    ctrlbus_diffdrive_pose_advance(&pose, full, -full, 236.0f);
    ctrlbus_diffdrive_take_deadreckon(&pose, &dx, &dy, &dtheta);
    CHECK_NEAR(dtheta / Q16, -360.0, 0.01);
    CHECK_NEAR(dx / Q16, 0.0, 0.01);
    CHECK_NEAR(dy / Q16, 0.0, 0.01);
}

static void test_arc(void)
{
    /* A quarter circle of radius 500 mm anticlockwise ends at (500, 500), whether it is
     * integrated in one step or in many. */
    const double radius = 500.0;
    const double half_track = 118.0;
    const float left = (float)((radius - half_track) * PI / 2.0);
    const float right = (float)((radius + half_track) * PI / 2.0);
    const int pieces[] = {1, 7, 100};
    for (size_t i = 0; i < sizeof pieces / sizeof pieces[0]; i++) {
        harness_context("%d pieces", pieces[i]);
        ctrlbus_diffdrive_pose_t pose;
        ctrlbus_diffdrive_pose_reset(&pose, 0.0f, 0.0f);
        for (int k = 0; k < pieces[i]; k++) {
            ctrlbus_diffdrive_pose_advance(&pose, left / (float)pieces[i],
                                           right / (float)pieces[i], (float)(2.0 * half_track));
        }
        int32_t dx = 0;
        int32_t dy = 0;
        int32_t dtheta = 0;
        ctrlbus_diffdrive_take_deadreckon(&pose, &dx, &dy, &dtheta);
        CHECK_NEAR(dx / Q16, radius, 0.05);
        CHECK_NEAR(dy / Q16, radius, 0.05);
        CHECK_NEAR(dtheta / Q16, 90.0, 0.001);
    }
    harness_context(NULL);
}

static void test_saturation_is_reported_later(void)
{
    ctrlbus_diffdrive_pose_t pose;
    ctrlbus_diffdrive_pose_reset(&pose, 0.0f, 0.0f);
    ctrlbus_diffdrive_pose_advance(&pose, 40000.0f, 40000.0f, 236.0f); /* 40 m: beyond Q16 mm */
    int32_t dx = 0;
    int32_t dy = 0;
    int32_t dtheta = 0;
    ctrlbus_diffdrive_take_deadreckon(&pose, &dx, &dy, &dtheta);
    CHECK_EQ(dx, INT32_MAX);
    /* What did not fit is not lost: the next answer carries it. */
    ctrlbus_diffdrive_take_deadreckon(&pose, &dx, &dy, &dtheta);
    CHECK_NEAR(dx / Q16 + INT32_MAX / Q16, 40000.0, 0.01);
    CHECK_EQ(dy, 0);
    CHECK_EQ(dtheta, 0);
}

static void test_rounding_remainders_do_not_add_up(void)
{
    /* 1000 answers of a motion worth 0.4 Q16 units each: rounding each one on its own would
     * report nothing at all; carrying the remainders reports the 400 units the robot moved. */
    ctrlbus_diffdrive_pose_t pose;
    ctrlbus_diffdrive_pose_reset(&pose, 0.0f, 0.0f);
    const float step_mm = (float)(0.4 / Q16);
    int64_t reported = 0;
    for (int i = 0; i < 1000; i++) {
        ctrlbus_diffdrive_pose_advance(&pose, step_mm, step_mm, 236.0f);
        int32_t dx = 0;
        ctrlbus_diffdrive_take_deadreckon(&pose, &dx, NULL, NULL);
        reported += dx;
    }
    CHECK_NEAR((double)reported, 400.0, 2.0);
}

int main(void)
{
    RUN(test_wheel_speeds);
    RUN(test_wheel_speeds_match_reference);
    RUN(test_straight_and_turns);
    RUN(test_arc);
    RUN(test_saturation_is_reported_later);
    RUN(test_rounding_remainders_do_not_add_up);
    return harness_finish();
}
