/* SPDX-License-Identifier: MIT */
/* Unit tests of the simulated base (its differential-drive math is the library's, tested in
 * c/tests/test_diffdrive.c). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>

#include "simbase.h"

static int failures;

#define CHECK(cond)                                                                                                    \
    do {                                                                                                               \
        if (!(cond)) {                                                                                                 \
            printf("%s:%d: check failed: %s\n", __FILE__, __LINE__, #cond);                                           \
            failures++;                                                                                                \
        }                                                                                                              \
    } while (0)

#define CHECK_NEAR(actual, expected, tolerance)                                                                        \
    do {                                                                                                               \
        double actual_ = (double)(actual);                                                                             \
        double expected_ = (double)(expected);                                                                         \
        if (fabs(actual_ - expected_) > (double)(tolerance)) {                                                         \
            printf("%s:%d: %s = %.6f, expected %.6f +- %g\n", __FILE__, __LINE__, #actual, actual_, expected_,         \
                   (double)(tolerance));                                                                               \
            failures++;                                                                                                \
        }                                                                                                              \
    } while (0)

#define Q16 65536.0

static void test_defaults_and_start(void)
{
    simbase_t sim;
    simbase_init(&sim, NULL);
    CHECK(simbase_battery_percent(&sim) == 80);
    CHECK(simbase_power_status(&sim) == 0);
    CHECK(simbase_bumper_bitmap(&sim) == 0xFFFFFFFFu);
    CHECK(simbase_motor_status(&sim) == 0);
    CHECK(simbase_radius_mm(&sim) == 170);
    int32_t left = -1;
    int32_t right = -1;
    simbase_wheel_travel_mm(&sim, &left, &right);
    CHECK(left == 0 && right == 0);
    /* It starts facing the dock: the main probe sees the main beacon, the side probes nothing. */
    uint8_t probes[SIMBASE_PROBE_COUNT] = {0xFF, 0xFF, 0xFF};
    simbase_probe_beacons(&sim, probes);
    CHECK(probes[0] == 0);
    CHECK(probes[1] == SIMBASE_BEACON_MAIN);
    CHECK(probes[2] == 0);
}

static void test_acceleration_limit(void)
{
    simbase_t sim;
    simbase_init(&sim, NULL);
    simbase_set_wheel_speeds(&sim, 500, 500);
    simbase_step(&sim, 100);
    /* 1500 mm/s^2 for 100 ms in 10 ms steps: speeds 15, 30, ... 150 mm/s; 8.25 mm travelled. */
    CHECK_NEAR(sim.left_mm_s, 150.0, 0.01);
    int32_t dx = 0;
    int32_t dy = 0;
    int32_t dtheta = 0;
    simbase_take_deadreckon(&sim, &dx, &dy, &dtheta);
    CHECK_NEAR(dx / Q16, 8.25, 0.001);
    CHECK_NEAR(dy / Q16, 0.0, 0.001);
    CHECK(dtheta == 0);
    /* Commands beyond the maximum are clamped. */
    simbase_set_wheel_speeds(&sim, 5000, -5000);
    CHECK_NEAR(sim.target_left_mm_s, 1000.0, 0.0);
    CHECK_NEAR(sim.target_right_mm_s, -1000.0, 0.0);
}

static void test_velocity_command(void)
{
    simbase_t sim;
    simbase_init(&sim, NULL);
    simbase_set_velocity(&sim, 13107, 32768);
    CHECK_NEAR(sim.target_left_mm_s, 141.0, 0.0);
    CHECK_NEAR(sim.target_right_mm_s, 259.0, 0.0);
}

static void test_docking_and_charging(void)
{
    simbase_t sim;
    simbase_init(&sim, NULL);
    simbase_set_wheel_speeds(&sim, 300, 300);
    simbase_step(&sim, 5000); /* 1000 mm at 300 mm/s: there in under 4 s */
    CHECK(simbase_power_status(&sim) == (SIMBASE_POWER_ON_DOCK | SIMBASE_POWER_CHARGING));
    CHECK(simbase_bumpers_pressed(&sim) == 0); /* the dock's face is not an obstacle hit */
    CHECK(simbase_motor_status(&sim) & SIMBASE_MOTOR_STALL);
    CHECK_NEAR(sim.pose.x_mm, 170.0, 0.01);
    int32_t left = 0;
    int32_t right = 0;
    simbase_wheel_travel_mm(&sim, &left, &right);
    CHECK(left == 1000 && right == 1000);
    /* The front sensor touches the dock: 1 mm, not 0 (which would mean no echo). */
    CHECK(simbase_distance_mm_q16(&sim, 0) == 65536u);
    uint8_t probes[SIMBASE_PROBE_COUNT] = {0};
    simbase_probe_beacons(&sim, probes);
    CHECK(probes[1] & SIMBASE_BEACON_MAIN);

    simbase_set_wheel_speeds(&sim, 0, 0);
    simbase_step(&sim, 100);
    CHECK((simbase_motor_status(&sim) & SIMBASE_MOTOR_STALL) == 0);
    int32_t before = sim.battery_micropercent;
    simbase_step(&sim, 10000); /* 0.1 % a second on the dock, less the idle drain */
    CHECK(sim.battery_micropercent == before + 1000000 - 5000);
    simbase_step(&sim, 10000);
    for (int i = 0; i < 30; i++) {
        simbase_step(&sim, 10000);
    }
    CHECK(simbase_battery_percent(&sim) == 100);
    CHECK(simbase_power_status(&sim) == SIMBASE_POWER_ON_DOCK);

    /* Backing off the dock ends charging. */
    simbase_set_wheel_speeds(&sim, -200, -200);
    simbase_step(&sim, 1000);
    CHECK(simbase_power_status(&sim) == 0);
}

static void test_bumpers(void)
{
    simbase_t sim;
    simbase_init(&sim, NULL);
    /* Head-on into the wall x = 4000: both bumpers, stopped at the wall. */
    simbase_place(&sim, 3700, 1500, 0);
    simbase_set_wheel_speeds(&sim, 300, 300);
    simbase_step(&sim, 2000);
    CHECK(simbase_bumpers_pressed(&sim) == (SIMBASE_BUMPER_LEFT | SIMBASE_BUMPER_RIGHT));
    CHECK(simbase_bumper_bitmap(&sim) == 0xFFFFFFFCu);
    CHECK_NEAR(sim.pose.x_mm, 4000.0 - 170.0, 0.01);
    CHECK_NEAR(sim.left_mm_s, 0.0, 0.0);
    int32_t left_before = 0;
    int32_t right_before = 0;
    simbase_wheel_travel_mm(&sim, &left_before, &right_before);

    /* Forward is refused while pressed, backward is obeyed and clears the bumpers. */
    simbase_set_wheel_speeds(&sim, 200, 200);
    CHECK_NEAR(sim.target_left_mm_s, 0.0, 0.0);
    simbase_step(&sim, 1000);
    int32_t left = 0;
    int32_t right = 0;
    simbase_wheel_travel_mm(&sim, &left, &right);
    CHECK(left == left_before && right == right_before);
    simbase_set_wheel_speeds(&sim, -200, -200);
    simbase_step(&sim, 500);
    CHECK(simbase_bumpers_pressed(&sim) == 0);
    CHECK(simbase_bumper_bitmap(&sim) == 0xFFFFFFFFu);
    CHECK(sim.pose.x_mm < 4000.0f - 170.0f);

    /* A wall ahead and to the right presses the right bumper only. */
    simbase_place(&sim, 3700, 1500, 30);
    simbase_set_wheel_speeds(&sim, 300, 300);
    simbase_step(&sim, 3000);
    CHECK(simbase_bumpers_pressed(&sim) == SIMBASE_BUMPER_RIGHT);
    CHECK(simbase_bumper_bitmap(&sim) == 0xFFFFFFFDu);
    /* ... and one ahead and to the left, the left one. */
    simbase_place(&sim, 3700, 1500, -30);
    simbase_set_wheel_speeds(&sim, 300, 300);
    simbase_step(&sim, 3000);
    CHECK(simbase_bumpers_pressed(&sim) == SIMBASE_BUMPER_LEFT);

    /* Backing into a wall presses nothing (no rear bumper) but stalls the wheels. */
    simbase_place(&sim, 3700, 1500, 180);
    simbase_set_wheel_speeds(&sim, -300, -300);
    simbase_step(&sim, 3000);
    CHECK(simbase_bumpers_pressed(&sim) == 0);
    CHECK(simbase_motor_status(&sim) & SIMBASE_MOTOR_STALL);
}

static void test_distance_sensors(void)
{
    simbase_t sim;
    simbase_init(&sim, NULL);
    simbase_place(&sim, 3000, 1500, 0);
    CHECK_NEAR(simbase_distance_mm_q16(&sim, 0) / Q16, 830.0, 0.01);                    /* ahead */
    CHECK_NEAR(simbase_distance_mm_q16(&sim, 1) / Q16, (4000.0 - 3000.0 - 130.2) / 0.76604444, 0.5); /* +40 */
    CHECK_NEAR(simbase_distance_mm_q16(&sim, 3) / Q16, 1330.0, 0.01);                   /* left */
    CHECK_NEAR(simbase_distance_mm_q16(&sim, 4) / Q16, 1330.0, 0.01);                   /* right */
    CHECK(simbase_distance_mm_q16(&sim, 5) == 0);
    /* Facing the far wall 2.8 m away: beyond the 2 m range, no echo. */
    simbase_place(&sim, 1000, 1500, 0);
    CHECK(simbase_distance_mm_q16(&sim, 0) == 0);
    /* Turned by 90 degrees, the front sensor looks at the wall y = 3000. */
    simbase_place(&sim, 1000, 1500, 90);
    CHECK_NEAR(simbase_distance_mm_q16(&sim, 0) / Q16, 1330.0, 0.01);
}

static void test_beacon_sectors(void)
{
    simbase_t sim;
    simbase_init(&sim, NULL);
    uint8_t probes[SIMBASE_PROBE_COUNT] = {0};
    /* Off to the dock's left (+y), facing it: the main probe sees only the left beacon. */
    simbase_place(&sim, 1000, 2200, 215);
    simbase_probe_beacons(&sim, probes);
    CHECK(probes[1] == SIMBASE_BEACON_LEFT);
    /* Mirrored: the right beacon. */
    simbase_place(&sim, 1000, 800, 145);
    simbase_probe_beacons(&sim, probes);
    CHECK(probes[1] == SIMBASE_BEACON_RIGHT);
    /* Facing away from the dock: nothing. */
    simbase_place(&sim, 1000, 1500, 0);
    simbase_probe_beacons(&sim, probes);
    CHECK(probes[0] == 0 && probes[1] == 0 && probes[2] == 0);
    /* Facing the dock but turned 50 degrees: the dock is in the left probe's view. */
    simbase_place(&sim, 1000, 1500, 130);
    simbase_probe_beacons(&sim, probes);
    CHECK(probes[0] == SIMBASE_BEACON_MAIN);
    CHECK(probes[1] == 0);
}

static void test_battery(void)
{
    simbase_t resting;
    simbase_t moving;
    simbase_init(&resting, NULL);
    simbase_init(&moving, NULL);
    simbase_set_wheel_speeds(&moving, -300, -300);
    simbase_step(&resting, 8000);
    simbase_step(&moving, 8000);
    /* 8 s at rest: 0.0005 %/s. Moving 2.4 m on top of that: 0.0002 %/mm, about 0.48 %. */
    CHECK(resting.battery_micropercent == 80000000 - 4000);
    CHECK(moving.battery_micropercent < resting.battery_micropercent - 450000);
    CHECK(moving.battery_micropercent > resting.battery_micropercent - 500000);

    /* An empty battery stops the wheels. */
    simbase_t empty;
    simbase_init(&empty, NULL);
    empty.battery_micropercent = 0;
    simbase_set_wheel_speeds(&empty, -300, -300);
    simbase_step(&empty, 1000);
    int32_t left = 0;
    int32_t right = 0;
    simbase_wheel_travel_mm(&empty, &left, &right);
    CHECK(left == 0 && right == 0);
    CHECK(simbase_battery_percent(&empty) == 0);
}

static void test_mounts_and_config(void)
{
    simbase_t sim;
    simbase_config_t config = {0};
    config.robot_radius_mm = 200;
    config.battery_start_percent = 150;
    simbase_init(&sim, &config);
    CHECK(simbase_battery_percent(&sim) == 100);
    simbase_mount_t mount;
    CHECK(simbase_sensor_mount(&sim, 1, &mount) == 0);
    CHECK(mount.x_mm == 153 && mount.y_mm == 129 && mount.angle_deg == 40 && mount.z_mm > 0);
    CHECK(simbase_sensor_mount(&sim, 4, &mount) == 0);
    CHECK(mount.x_mm == 0 && mount.y_mm == -200 && mount.angle_deg == 270);
    CHECK(simbase_sensor_mount(&sim, SIMBASE_SENSOR_COUNT, &mount) == -1);
    CHECK(mount.x_mm == 0 && mount.angle_deg == 0);
    CHECK(simbase_bumper_mount(&sim, 1, &mount) == 0);
    CHECK(mount.x_mm == 141 && mount.y_mm == -141 && mount.angle_deg == 315);
    CHECK(simbase_bumper_mount(&sim, 2, &mount) == -1);
}

static void test_long_step_is_bounded(void)
{
    simbase_t sim;
    simbase_init(&sim, NULL);
    simbase_set_wheel_speeds(&sim, -100, -100);
    simbase_step(&sim, UINT32_MAX); /* counts as 10 s */
    int32_t left = 0;
    int32_t right = 0;
    simbase_wheel_travel_mm(&sim, &left, &right);
    CHECK(left > -1000 && left < -900);
}

int main(void)
{
    test_defaults_and_start();
    test_acceleration_limit();
    test_velocity_command();
    test_docking_and_charging();
    test_bumpers();
    test_distance_sensors();
    test_beacon_sectors();
    test_battery();
    test_mounts_and_config();
    test_long_step_is_bounded();
    if (failures != 0) {
        printf("test_simbase: %d check(s) failed\n", failures);
        return 1;
    }
    printf("test_simbase: all checks passed\n");
    return 0;
}
