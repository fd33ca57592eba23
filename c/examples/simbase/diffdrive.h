/* Differential-drive math for a base: velocity commands to wheel speeds, and wheel travel to a
 * pose or to the dead-reckoning deltas that SET_V_AND_GET_DEADRECKON (0x41) answers.
 *
 * Issue 3 asks for this as a helper of the C library; until the library has it, it lives here,
 * used by the simulated base. Portable C99, no globals, no allocation, no libm: headings are kept
 * as a unit vector that is rotated by a short series, so the code fits small cores. */
#ifndef CTRLBUS_EXAMPLES_DIFFDRIVE_H
#define CTRLBUS_EXAMPLES_DIFFDRIVE_H

#include <stdint.h>

/* A pose in the plane: position in mm, heading as a unit vector, and the signed total turn in
 * radians since the pose was reset (not wrapped, so a full turn reads 2 pi, not 0). */
typedef struct {
    float x_mm;
    float y_mm;
    float heading_cos;
    float heading_sin;
    float turned_rad;
} diffdrive_pose_t;

/* Wheel speeds in mm/s from a SET_V_AND_GET_DEADRECKON command: `vx_mps_q16` forward speed
 * (m/s, Q16), `omega_radps_q16` turn rate (rad/s, Q16, positive = anticlockwise),
 * `half_track_mm` half the distance between the wheels. Rounds to the nearest mm/s and
 * saturates at the int32 range. Integer arithmetic only. ISR-safe; constant time. */
void diffdrive_wheel_speeds(int32_t vx_mps_q16, int32_t omega_radps_q16, int32_t half_track_mm,
                            int32_t *left_mm_s, int32_t *right_mm_s);

/* Set `pose` to (x_mm, y_mm) heading along +x with no turn recorded. Constant time. */
void diffdrive_pose_reset(diffdrive_pose_t *pose, float x_mm, float y_mm);

/* Turn `pose` on the spot by `angle_rad` (anticlockwise positive). Cost grows with |angle|:
 * one short series per 0.5 rad. */
void diffdrive_pose_turn(diffdrive_pose_t *pose, float angle_rad);

/* Move `pose` along the arc that wheel travels `left_mm` and `right_mm` describe (signed,
 * forward positive), for wheels `half_track_mm` from the centre (> 0). Exact for a constant-
 * curvature arc up to rounding. Cost as diffdrive_pose_turn for the arc's turn. */
void diffdrive_pose_advance(diffdrive_pose_t *pose, float left_mm, float right_mm, float half_track_mm);

/* Read `motion` as dead-reckoning deltas and start it again from zero: dx, dy in mm Q16 in the
 * frame the robot had when `motion` was last reset, dtheta in degrees Q16 (anticlockwise
 * positive), each rounded and saturated at the int32 range. This is the 0x41 answer when
 * `motion` is fed every wheel movement since the previous 0x41. Constant time. */
void diffdrive_take_deadreckon(diffdrive_pose_t *motion, int32_t *dx_mm_q16, int32_t *dy_mm_q16,
                               int32_t *dtheta_deg_q16);

#endif
