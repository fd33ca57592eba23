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
    /* Saturates instead of wrapping. */
    ctrlbus_diffdrive_wheel_speeds(INT32_MAX, INT32_MAX, INT32_MAX, &left, &right);
    CHECK_EQ(left, INT32_MIN);
    CHECK_EQ(right, INT32_MAX);
    /* NULL outputs are skipped. */
    ctrlbus_diffdrive_wheel_speeds(65536, 0, 236, NULL, &right);
    CHECK_EQ(right, 1000);
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
    RUN(test_straight_and_turns);
    RUN(test_arc);
    RUN(test_saturation_is_reported_later);
    RUN(test_rounding_remainders_do_not_add_up);
    return harness_finish();
}
