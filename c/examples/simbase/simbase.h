/* SPDX-License-Identifier: MIT */
/* A simulated differential-drive robot base, for the host base (posix_base) and the QEMU
 * firmware: the robot that the protocol stack reports on and drives.
 *
 * The world is a rectangular room, x from 0 to room_width_mm, y from 0 to room_depth_mm (x
 * right, y up, angles anticlockwise from +x). A charging dock sits in the middle of the wall
 * x = 0, facing +x; the robot docks forwards (front against the dock, like a Kobuki), which
 * puts it on charge. The robot starts 1.2 m in front of the dock, facing it.
 *
 * What it models:
 * - wheels: commanded speeds (mm/s), clamped to the maximum and approached at the acceleration
 *   limit; pose integrated from wheel travel; signed travel totals per wheel;
 * - walls: the robot stops at a wall; a wheel pushing into it sets the stall status bit;
 * - two bumpers, left (bit 0) and right (bit 1), that trigger when the front half of the body
 *   touches a wall (the dock's face excepted). As the reference base does, a pressed bumper
 *   stops the robot and forward wheel speeds are refused (set to 0) until it clears; backward
 *   speeds are obeyed;
 * - five distance sensors on the rim (0, +40, -40, +90, -90 degrees), ray cast against the
 *   walls; 0 means no echo within range, as the reference sends for a silent sonar;
 * - the dock's three IR beacons (left, main, right), each lighting a sector in front of the
 *   dock, seen by three probes on the robot's front (left, main, right);
 * - a battery that drains slowly at rest and more with motion, charges on the dock, and stops
 *   the wheels when empty.
 *
 * Time is passed in (simbase_step); nothing here reads a clock. No globals, no allocation, no
 * stdio, no libm. Floating point is single precision. Nothing here is ISR-safe: call it from the
 * main loop only. */
#ifndef CTRLBUS_EXAMPLES_SIMBASE_H
#define CTRLBUS_EXAMPLES_SIMBASE_H

#include <stdint.h>

#include "ctrlbus/diffdrive.h"

#define SIMBASE_SENSOR_COUNT 5u
#define SIMBASE_BUMPER_COUNT 2u
#define SIMBASE_PROBE_COUNT 3u /* probes and beacons: index 0 left, 1 main, 2 right */
#define SIMBASE_BEACON_COUNT 3u

/* Pressed bumpers as simbase_bumpers_pressed returns them (active high). */
#define SIMBASE_BUMPER_LEFT 0x01u
#define SIMBASE_BUMPER_RIGHT 0x02u

/* Probe bitmaps (GET_CHARGER_DATA): which dock beacons a probe sees. */
#define SIMBASE_BEACON_LEFT 0x01u
#define SIMBASE_BEACON_MAIN 0x02u
#define SIMBASE_BEACON_RIGHT 0x04u

/* Power status (GET_BASE_STATUS): charging, DC (cable, never set here), on the dock. */
#define SIMBASE_POWER_CHARGING 0x01u
#define SIMBASE_POWER_DC 0x02u
#define SIMBASE_POWER_ON_DOCK 0x04u

/* Motor status (GET_BASE_MOTOR_DATA, SET_V_AND_GET_DEADRECKON). */
#define SIMBASE_MOTOR_STALL 0x02u

/* What to simulate. Zero (or a negative value) in a field means its default. */
typedef struct {
    int32_t room_width_mm;         /* x extent; default 4000 */
    int32_t room_depth_mm;         /* y extent; default 3000 */
    int32_t robot_radius_mm;       /* default 170 */
    int32_t half_track_mm;         /* half the distance between the wheels; default 118 */
    int32_t max_wheel_speed_mm_s;  /* commands beyond it are clamped; default 1000 */
    int32_t wheel_accel_mm_s2;     /* acceleration limit of each wheel; default 1500 */
    int32_t sensor_range_mm;       /* farthest echo the distance sensors report; default 2000 */
    int32_t battery_start_percent; /* default 80 (1..100) */
} simbase_config_t;

/* Where a sensor or bumper sits on the robot, in the units of GET_BASE_CONF before the Q8
 * scaling: mm from the robot centre (x forward, y left, z up), angle in degrees 0..359. */
typedef struct {
    int32_t x_mm;
    int32_t y_mm;
    int32_t z_mm;
    int32_t angle_deg;
} simbase_mount_t;

/* The simulation state; fields are private to simbase.c. */
typedef struct {
    simbase_config_t config; /* with defaults filled in */
    ctrlbus_diffdrive_pose_t pose;   /* robot centre in room coordinates */
    ctrlbus_diffdrive_pose_t since_deadreckon;
    float target_left_mm_s;
    float target_right_mm_s;
    float left_mm_s;
    float right_mm_s;
    int64_t left_travel_um;
    int64_t right_travel_um;
    int32_t battery_micropercent; /* 1e-6 %: fine enough for the slow idle drain */
    uint8_t bumpers;
    uint8_t motor_status;
    uint8_t on_dock;
} simbase_t;

/* Start a simulation: defaults for the zero fields of `config` (NULL: all defaults), the robot
 * at its start pose, at rest. Constant time. */
void simbase_init(simbase_t *sim, const simbase_config_t *config);

/* Put the robot at (x_mm, y_mm) facing `heading_deg` (anticlockwise from +x), at rest, kept at
 * least a radius away from every wall. For tests and scenarios; cost grows with |heading|. */
void simbase_place(simbase_t *sim, int32_t x_mm, int32_t y_mm, int32_t heading_deg);

/* Advance the simulation by `dt_ms` milliseconds (in steps of 10 ms at most). A `dt_ms` above
 * 10000 counts as 10000: after a long stall the simulation does not try to catch up. Cost:
 * proportional to dt_ms / 10. */
void simbase_step(simbase_t *sim, uint32_t dt_ms);

/* Command wheel speeds in mm/s (signed, forward positive). Clamped to the maximum speed; forward
 * speeds are refused (0) while a bumper is pressed. The wheels reach them at the acceleration
 * limit. Constant time. */
void simbase_set_wheel_speeds(simbase_t *sim, int32_t left_mm_s, int32_t right_mm_s);

/* Command a body velocity as SET_V_AND_GET_DEADRECKON does (vx m/s Q16, omega rad/s Q16);
 * converted with the configured half track and passed to simbase_set_wheel_speeds. */
void simbase_set_velocity(simbase_t *sim, int32_t vx_mps_q16, int32_t omega_radps_q16);

/* The motion since the previous call (or since init) as 0x41 deadreckon deltas; restarts it. */
void simbase_take_deadreckon(simbase_t *sim, int32_t *dx_mm_q16, int32_t *dy_mm_q16, int32_t *dtheta_deg_q16);

/* Signed travel totals of each wheel since init, in whole mm (rounded towards zero). */
void simbase_wheel_travel_mm(const simbase_t *sim, int32_t *left_mm, int32_t *right_mm);

/* Motor status bits (SIMBASE_MOTOR_STALL while a wheel pushes against a wall). */
uint8_t simbase_motor_status(const simbase_t *sim);

/* Battery charge, 0..100 %. */
uint8_t simbase_battery_percent(const simbase_t *sim);

/* Power status bits: SIMBASE_POWER_ON_DOCK on the dock, plus SIMBASE_POWER_CHARGING there
 * until the battery is full. */
uint8_t simbase_power_status(const simbase_t *sim);

/* Pressed bumpers, active high (SIMBASE_BUMPER_*). */
uint8_t simbase_bumpers_pressed(const simbase_t *sim);

/* The GET_BASE_BUMPER_DATA bitmap: active low, so all ones when nothing is pressed. */
uint32_t simbase_bumper_bitmap(const simbase_t *sim);

/* Distance seen by sensor `index` (< SIMBASE_SENSOR_COUNT) in mm Q16, 0 when the nearest wall
 * is beyond the sensor range (or for an index out of range); a wall touching the sensor reads
 * 1 mm, so that 0 keeps meaning "no echo". Constant time. */
uint32_t simbase_distance_mm_q16(const simbase_t *sim, uint32_t index);

/* The beacons each probe sees now: probes[0] left, [1] main, [2] right, SIMBASE_BEACON_* bits. */
void simbase_probe_beacons(const simbase_t *sim, uint8_t probes[SIMBASE_PROBE_COUNT]);

/* Mounting of distance sensor / bumper `index` on the robot; 0 on success, -1 when index is out
 * of range (then *mount is zeroed). */
int simbase_sensor_mount(const simbase_t *sim, uint32_t index, simbase_mount_t *mount);
int simbase_bumper_mount(const simbase_t *sim, uint32_t index, simbase_mount_t *mount);

/* Robot radius in mm, for GET_BASE_CONF. */
int32_t simbase_radius_mm(const simbase_t *sim);

#endif
