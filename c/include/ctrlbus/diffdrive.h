/* SPDX-License-Identifier: MIT */
/* ctrlbus differential-drive helpers: the math a two-wheel base needs around the Control Bus.
 *
 *   - SET_V_AND_GET_DEADRECKON (0x41) commands a body velocity (vx m/s Q16, omega rad/s Q16);
 *     ctrlbus_diffdrive_wheel_speeds() turns it into wheel speeds (mm/s);
 *   - the 0x41 answer reports the motion since the previous 0x41 as deltas (mm Q16, degrees Q16)
 *     in the robot frame at the start of that interval: feed every wheel movement to a
 *     ctrlbus_diffdrive_pose_t with ctrlbus_diffdrive_pose_advance() and read it out with
 *     ctrlbus_diffdrive_take_deadreckon().
 *
 * The formulas are docs/protocol.md §9.4 [kinematics], with `wheel_track_mm` the distance between
 * the two wheels (the reference quotes half of it: 80 mm for SDP Mini, 118 mm for base_ref v4, so
 * wheel tracks of 160 and 236 mm). Positive omega turns left (anticlockwise), so the right wheel
 * runs faster. The Python twin is ctrlbus.kinematics.
 *
 * This header is separate from the base stack (ctrlbus/base.h): a firmware links only what it
 * calls. The wheel-speed conversion is integer arithmetic; the pose functions use single
 * precision floats (software floating point on a core without an FPU) and no libm: headings are
 * kept as a unit vector rotated by a short series. Nothing here has state of its own; every
 * function touches only its arguments, so all are ISR-safe on distinct poses.
 */
#ifndef CTRLBUS_DIFFDRIVE_H
#define CTRLBUS_DIFFDRIVE_H

#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* A pose in the plane, or a motion accumulated since some start: position in mm, heading as a
 * unit vector, and the signed total turn in radians since the pose was reset (not wrapped, so a
 * full turn reads 2 pi, not 0). Caller-owned; the fields may be read directly. */
typedef struct {
    float x_mm;
    float y_mm;
    float heading_cos;
    float heading_sin;
    float turned_rad;
} ctrlbus_diffdrive_pose_t;

/* Wheel speeds in mm/s for a body velocity: vx_mps_q16 forward (m/s, Q16), omega_radps_q16 turn
 * rate (rad/s, Q16, positive = anticlockwise), wheel_track_mm the distance between the wheels
 * (as ctrlbus_base_limits_t holds it): left = 1000 vx - omega W / 2, right = 1000 vx + omega W / 2.
 * Each is rounded to the nearest mm/s (halves away from zero), exactly, for every input: the
 * results always fit (|speed| < 2^31). 32-bit integer arithmetic only (no 64-bit multiply).
 * Returns nothing; NULL outputs are skipped. ISR-safe. Cost: O(1) (four 32-bit products). */
void ctrlbus_diffdrive_wheel_speeds(int32_t vx_mps_q16, int32_t omega_radps_q16,
                                    uint16_t wheel_track_mm, int32_t *left_mm_s,
                                    int32_t *right_mm_s);

/* Sets pose to (x_mm, y_mm), heading along +x, no turn recorded. ISR-safe. Cost: O(1). */
void ctrlbus_diffdrive_pose_reset(ctrlbus_diffdrive_pose_t *pose, float x_mm, float y_mm);

/* Turns pose on the spot by angle_rad (anticlockwise positive). ISR-safe.
 * Cost: one short series (about 30 float operations) per started 0.5 rad of |angle_rad|. */
void ctrlbus_diffdrive_pose_turn(ctrlbus_diffdrive_pose_t *pose, float angle_rad);

/* Moves pose along the arc that the wheel travels left_mm and right_mm (signed, forward
 * positive) describe, for wheels wheel_track_mm apart (> 0): distance (l + r) / 2, turn
 * (r - l) / W radians. Exact for a constant-curvature arc up to float rounding, so any split of a
 * movement into steps gives the same result. ISR-safe. Cost: as ctrlbus_diffdrive_pose_turn()
 * for the arc's turn, twice. */
void ctrlbus_diffdrive_pose_advance(ctrlbus_diffdrive_pose_t *pose, float left_mm, float right_mm,
                                    float wheel_track_mm);

/* Reads motion (the movement since the previous call, fed with ctrlbus_diffdrive_pose_advance())
 * as a 0x41 answer's deltas: dx, dy in mm Q16 in the frame the robot had at the previous call,
 * dtheta in degrees Q16 (anticlockwise positive), each rounded to nearest and saturated at the
 * int32 range. Then restarts motion from what was not reported (protocol.md §9.4): the rounding
 * remainders, and any excess a saturated value could not carry, expressed in the frame of the
 * reported motion, so that they are reported later instead of lost. NULL outputs are skipped.
 * ISR-safe. Cost: O(1) (a few dozen float operations). */
void ctrlbus_diffdrive_take_deadreckon(ctrlbus_diffdrive_pose_t *motion, int32_t *dx_mm_q16,
                                       int32_t *dy_mm_q16, int32_t *dtheta_deg_q16);

#ifdef __cplusplus
}
#endif

#endif
