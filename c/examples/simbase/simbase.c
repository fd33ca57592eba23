/* SPDX-License-Identifier: MIT */
/* The simulated base; see simbase.h for the model. */
#include "simbase.h"

#include <stddef.h>

#define STEP_MAX_MS 10u
#define STEP_CALL_MAX_MS 10000u

#define START_DISTANCE_FROM_DOCK_MM 1000.0f

/* The dock: centred on the wall x = 0, its face flush with the wall. Its beacons shine from a
 * point a little behind the face, so that a docked robot's main probe still sees them. */
#define DOCK_HALF_WIDTH_MM 100.0f
#define DOCK_BEACON_DEPTH_MM 30.0f
#define DOCK_ALIGN_TOLERANCE_MM 40.0f
#define DOCK_HEADING_COS_MIN 0.9397f /* cos 20 degrees: how squarely the robot must face it */
#define CONTACT_TOLERANCE_MM 0.5f
#define DOCK_CONTACT_TOLERANCE_MM 2.0f

/* Beacon sectors seen from the dock, by the tangent of the angle off the dock's axis:
 * main within +-12 degrees, left from +4 to +70 (the dock's left is +y), right mirrored. */
#define MAIN_SECTOR_TAN 0.21255656f
#define SIDE_SECTOR_TAN_MIN 0.06992681f
#define SIDE_SECTOR_TAN_MAX 2.74747742f
#define BEACON_RANGE_MM 3000.0f
#define PROBE_FOV_COS_SQUARED 0.75f /* probes see +-30 degrees around their axis */

/* A contact counts for the front bumpers when it is within +-80 degrees of straight ahead; a
 * contact within +-10 degrees of straight ahead presses both. */
#define FRONT_CONTACT_COS 0.17364818f
#define BOTH_BUMPERS_SIN 0.17364818f

/* Battery model, in millionths of a percent: 0.0005 % per second at rest, 0.0002 % per mm of
 * wheel travel, 0.1 % per second on the dock. */
#define MICROPERCENT_PER_PERCENT 1000000
#define BATTERY_FULL_MICROPERCENT (100 * MICROPERCENT_PER_PERCENT)
#define BATTERY_IDLE_DRAIN_PER_S 500.0f
#define BATTERY_DRAIN_PER_MM 200.0f
#define BATTERY_CHARGE_PER_S 100000.0f

#define SENSOR_HEIGHT_MM 60
#define BUMPER_HEIGHT_MM 30
#define MIN_ECHO_MM 1.0f
#define RADIANS_PER_DEGREE 0.017453292519943295f

typedef struct {
    float cos_a;
    float sin_a;
    int32_t angle_deg;
} mount_direction_t;

static const mount_direction_t sensor_directions[SIMBASE_SENSOR_COUNT] = {
    {1.0f, 0.0f, 0},
    {0.76604444f, 0.64278761f, 40},
    {0.76604444f, -0.64278761f, 320},
    {0.0f, 1.0f, 90},
    {0.0f, -1.0f, 270},
};

static const mount_direction_t bumper_directions[SIMBASE_BUMPER_COUNT] = {
    {0.70710678f, 0.70710678f, 45},
    {0.70710678f, -0.70710678f, 315},
};

static const mount_direction_t probe_directions[SIMBASE_PROBE_COUNT] = {
    {0.64278761f, 0.76604444f, 50},
    {1.0f, 0.0f, 0},
    {0.64278761f, -0.76604444f, 310},
};

static int32_t or_default(int32_t value, int32_t fallback)
{
    return value > 0 ? value : fallback;
}

static float min_f(float a, float b)
{
    return a < b ? a : b;
}

static float max_f(float a, float b)
{
    return a > b ? a : b;
}

static float abs_f(float a)
{
    return a < 0.0f ? -a : a;
}

static float room_width(const simbase_t *sim)
{
    return (float)sim->config.room_width_mm;
}

static float room_depth(const simbase_t *sim)
{
    return (float)sim->config.room_depth_mm;
}

static float radius(const simbase_t *sim)
{
    return (float)sim->config.robot_radius_mm;
}

void simbase_init(simbase_t *sim, const simbase_config_t *config)
{
    simbase_config_t given = {0};
    if (config != NULL) {
        given = *config;
    }
    simbase_t fresh = {0};
    *sim = fresh;
    sim->config.robot_radius_mm = or_default(given.robot_radius_mm, 170);
    /* The room must leave the robot somewhere to stand. */
    sim->config.room_width_mm = or_default(given.room_width_mm, 4000);
    sim->config.room_depth_mm = or_default(given.room_depth_mm, 3000);
    if (sim->config.room_width_mm < 4 * sim->config.robot_radius_mm) {
        sim->config.room_width_mm = 4 * sim->config.robot_radius_mm;
    }
    if (sim->config.room_depth_mm < 4 * sim->config.robot_radius_mm) {
        sim->config.room_depth_mm = 4 * sim->config.robot_radius_mm;
    }
    sim->config.half_track_mm = or_default(given.half_track_mm, 118);
    sim->config.max_wheel_speed_mm_s = or_default(given.max_wheel_speed_mm_s, 1000);
    sim->config.wheel_accel_mm_s2 = or_default(given.wheel_accel_mm_s2, 1500);
    sim->config.sensor_range_mm = or_default(given.sensor_range_mm, 2000);
    sim->config.battery_start_percent = or_default(given.battery_start_percent, 80);
    if (sim->config.battery_start_percent > 100) {
        sim->config.battery_start_percent = 100;
    }

    float start_x = min_f(radius(sim) + START_DISTANCE_FROM_DOCK_MM, room_width(sim) / 2.0f);
    ctrlbus_diffdrive_pose_reset(&sim->pose, start_x, room_depth(sim) / 2.0f);
    sim->pose.heading_cos = -1.0f; /* facing the dock */
    ctrlbus_diffdrive_pose_reset(&sim->since_deadreckon, 0.0f, 0.0f);
    sim->battery_micropercent = sim->config.battery_start_percent * MICROPERCENT_PER_PERCENT;
}

static float clamp_speed(const simbase_t *sim, int32_t speed_mm_s)
{
    int32_t limit = sim->config.max_wheel_speed_mm_s;
    if (speed_mm_s > limit) {
        speed_mm_s = limit;
    } else if (speed_mm_s < -limit) {
        speed_mm_s = -limit;
    }
    return (float)speed_mm_s;
}

/* The reference base's local safety: while a bumper is pressed, no wheel may go forward. */
static void refuse_forward_while_bumped(simbase_t *sim)
{
    if (sim->bumpers == 0) {
        return;
    }
    sim->target_left_mm_s = min_f(sim->target_left_mm_s, 0.0f);
    sim->target_right_mm_s = min_f(sim->target_right_mm_s, 0.0f);
    sim->left_mm_s = min_f(sim->left_mm_s, 0.0f);
    sim->right_mm_s = min_f(sim->right_mm_s, 0.0f);
}

void simbase_set_wheel_speeds(simbase_t *sim, int32_t left_mm_s, int32_t right_mm_s)
{
    sim->target_left_mm_s = clamp_speed(sim, left_mm_s);
    sim->target_right_mm_s = clamp_speed(sim, right_mm_s);
    refuse_forward_while_bumped(sim);
}

void simbase_set_velocity(simbase_t *sim, int32_t vx_mps_q16, int32_t omega_radps_q16)
{
    int32_t left = 0;
    int32_t right = 0;
    uint16_t track = (uint16_t)(2 * sim->config.half_track_mm); /* a u16, as the limits hold it */
    ctrlbus_diffdrive_wheel_speeds(vx_mps_q16, omega_radps_q16, track, &left, &right);
    simbase_set_wheel_speeds(sim, left, right);
}

static float approach(float current, float target, float max_change)
{
    if (target > current + max_change) {
        return current + max_change;
    }
    if (target < current - max_change) {
        return current - max_change;
    }
    return target;
}

/* How much of the straight move from (x, y) by (dx, dy) keeps the robot inside the walls. */
static float free_fraction(const simbase_t *sim, float x, float y, float dx, float dy)
{
    float r = radius(sim);
    float fraction = 1.0f;
    if (dx < 0.0f && x + dx < r) {
        fraction = min_f(fraction, (x - r) / -dx);
    } else if (dx > 0.0f && x + dx > room_width(sim) - r) {
        fraction = min_f(fraction, (room_width(sim) - r - x) / dx);
    }
    if (dy < 0.0f && y + dy < r) {
        fraction = min_f(fraction, (y - r) / -dy);
    } else if (dy > 0.0f && y + dy > room_depth(sim) - r) {
        fraction = min_f(fraction, (room_depth(sim) - r - y) / dy);
    }
    return max_f(fraction, 0.0f);
}

static int64_t mm_to_um(float mm)
{
    float um = mm * 1000.0f;
    return (int64_t)(um >= 0.0f ? um + 0.5f : um - 0.5f);
}

static int is_dock_face(const simbase_t *sim, float y)
{
    return abs_f(y - room_depth(sim) / 2.0f) <= DOCK_HALF_WIDTH_MM;
}

/* Bumpers pressed by walls touching the front half of the body. */
static uint8_t touching_bumpers(const simbase_t *sim)
{
    const float r = radius(sim);
    const float x = sim->pose.x_mm;
    const float y = sim->pose.y_mm;
    /* Each wall: the gap to it and the direction from the robot towards it. */
    const struct {
        float gap;
        float nx;
        float ny;
        int dock_wall;
    } walls[4] = {
        {x - r, -1.0f, 0.0f, 1},
        {room_width(sim) - x - r, 1.0f, 0.0f, 0},
        {y - r, 0.0f, -1.0f, 0},
        {room_depth(sim) - y - r, 0.0f, 1.0f, 0},
    };
    uint8_t pressed = 0;
    for (size_t i = 0; i < 4u; i++) {
        if (walls[i].gap > CONTACT_TOLERANCE_MM) {
            continue;
        }
        float ahead = walls[i].nx * sim->pose.heading_cos + walls[i].ny * sim->pose.heading_sin;
        float leftwards = -walls[i].nx * sim->pose.heading_sin + walls[i].ny * sim->pose.heading_cos;
        if (ahead <= FRONT_CONTACT_COS) {
            continue;
        }
        if (walls[i].dock_wall && is_dock_face(sim, y)) {
            continue; /* the dock's charging contacts, not an obstacle hit */
        }
        if (leftwards > -BOTH_BUMPERS_SIN) {
            pressed |= SIMBASE_BUMPER_LEFT;
        }
        if (leftwards < BOTH_BUMPERS_SIN) {
            pressed |= SIMBASE_BUMPER_RIGHT;
        }
    }
    return pressed;
}

static uint8_t is_docked(const simbase_t *sim)
{
    return sim->pose.x_mm <= radius(sim) + DOCK_CONTACT_TOLERANCE_MM &&
           abs_f(sim->pose.y_mm - room_depth(sim) / 2.0f) <= DOCK_ALIGN_TOLERANCE_MM &&
           sim->pose.heading_cos <= -DOCK_HEADING_COS_MIN;
}

static void step_once(simbase_t *sim, float dt_s)
{
    if (sim->battery_micropercent <= 0) {
        sim->target_left_mm_s = 0.0f;
        sim->target_right_mm_s = 0.0f;
    }
    float max_change = (float)sim->config.wheel_accel_mm_s2 * dt_s;
    sim->left_mm_s = approach(sim->left_mm_s, sim->target_left_mm_s, max_change);
    sim->right_mm_s = approach(sim->right_mm_s, sim->target_right_mm_s, max_change);

    float left_mm = sim->left_mm_s * dt_s;
    float right_mm = sim->right_mm_s * dt_s;
    float wheel_track = 2.0f * (float)sim->config.half_track_mm;
    ctrlbus_diffdrive_pose_t next = sim->pose;
    ctrlbus_diffdrive_pose_advance(&next, left_mm, right_mm, wheel_track);
    float fraction = free_fraction(sim, sim->pose.x_mm, sim->pose.y_mm, next.x_mm - sim->pose.x_mm,
                                   next.y_mm - sim->pose.y_mm);
    if (fraction < 1.0f) {
        /* Blocked by a wall: the wheels only get as far as the wall lets the body go, and a
         * blocked wheel does not keep its speed. */
        left_mm *= fraction;
        right_mm *= fraction;
        sim->left_mm_s *= fraction;
        sim->right_mm_s *= fraction;
        next = sim->pose;
        ctrlbus_diffdrive_pose_advance(&next, left_mm, right_mm, wheel_track);
        sim->motor_status |= SIMBASE_MOTOR_STALL;
    } else {
        sim->motor_status &= (uint8_t)~SIMBASE_MOTOR_STALL;
    }
    /* Keep rounding from ever leaving the body inside a wall. */
    float r = radius(sim);
    next.x_mm = min_f(max_f(next.x_mm, r), room_width(sim) - r);
    next.y_mm = min_f(max_f(next.y_mm, r), room_depth(sim) - r);
    sim->pose = next;
    ctrlbus_diffdrive_pose_advance(&sim->since_deadreckon, left_mm, right_mm, wheel_track);
    sim->left_travel_um += mm_to_um(left_mm);
    sim->right_travel_um += mm_to_um(right_mm);

    sim->bumpers = touching_bumpers(sim);
    refuse_forward_while_bumped(sim);
    sim->on_dock = is_docked(sim);

    float moved_mm = (abs_f(left_mm) + abs_f(right_mm)) / 2.0f;
    float change = (sim->on_dock ? BATTERY_CHARGE_PER_S * dt_s : 0.0f) - BATTERY_IDLE_DRAIN_PER_S * dt_s -
                   BATTERY_DRAIN_PER_MM * moved_mm;
    int32_t level = sim->battery_micropercent + (int32_t)(change >= 0.0f ? change + 0.5f : change - 0.5f);
    sim->battery_micropercent = level < 0 ? 0 : level > BATTERY_FULL_MICROPERCENT ? BATTERY_FULL_MICROPERCENT : level;
}

void simbase_place(simbase_t *sim, int32_t x_mm, int32_t y_mm, int32_t heading_deg)
{
    float r = radius(sim);
    float x = min_f(max_f((float)x_mm, r), room_width(sim) - r);
    float y = min_f(max_f((float)y_mm, r), room_depth(sim) - r);
    ctrlbus_diffdrive_pose_reset(&sim->pose, x, y);
    ctrlbus_diffdrive_pose_turn(&sim->pose, (float)(heading_deg % 360) * RADIANS_PER_DEGREE);
    sim->pose.turned_rad = 0.0f;
    sim->target_left_mm_s = 0.0f;
    sim->target_right_mm_s = 0.0f;
    sim->left_mm_s = 0.0f;
    sim->right_mm_s = 0.0f;
    sim->motor_status = 0;
    sim->bumpers = touching_bumpers(sim);
    sim->on_dock = is_docked(sim);
}

void simbase_step(simbase_t *sim, uint32_t dt_ms)
{
    if (dt_ms > STEP_CALL_MAX_MS) {
        dt_ms = STEP_CALL_MAX_MS;
    }
    while (dt_ms > 0u) {
        uint32_t step_ms = dt_ms < STEP_MAX_MS ? dt_ms : STEP_MAX_MS;
        step_once(sim, (float)step_ms / 1000.0f);
        dt_ms -= step_ms;
    }
}

void simbase_take_deadreckon(simbase_t *sim, int32_t *dx_mm_q16, int32_t *dy_mm_q16, int32_t *dtheta_deg_q16)
{
    ctrlbus_diffdrive_take_deadreckon(&sim->since_deadreckon, dx_mm_q16, dy_mm_q16, dtheta_deg_q16);
}

static int32_t um_to_mm(int64_t um)
{
    int64_t mm = um / 1000;
    if (mm > INT32_MAX) {
        return INT32_MAX;
    }
    if (mm < INT32_MIN) {
        return INT32_MIN;
    }
    return (int32_t)mm;
}

void simbase_wheel_travel_mm(const simbase_t *sim, int32_t *left_mm, int32_t *right_mm)
{
    *left_mm = um_to_mm(sim->left_travel_um);
    *right_mm = um_to_mm(sim->right_travel_um);
}

uint8_t simbase_motor_status(const simbase_t *sim)
{
    return sim->motor_status;
}

uint8_t simbase_battery_percent(const simbase_t *sim)
{
    return (uint8_t)((sim->battery_micropercent + MICROPERCENT_PER_PERCENT / 2) / MICROPERCENT_PER_PERCENT);
}

uint8_t simbase_power_status(const simbase_t *sim)
{
    if (!sim->on_dock) {
        return 0;
    }
    return sim->battery_micropercent < BATTERY_FULL_MICROPERCENT ? SIMBASE_POWER_ON_DOCK | SIMBASE_POWER_CHARGING
                                                                 : SIMBASE_POWER_ON_DOCK;
}

uint8_t simbase_bumpers_pressed(const simbase_t *sim)
{
    return sim->bumpers;
}

uint32_t simbase_bumper_bitmap(const simbase_t *sim)
{
    return ~(uint32_t)sim->bumpers;
}

/* A direction fixed on the robot, turned into room coordinates. */
static void to_room(const simbase_t *sim, const mount_direction_t *mount, float *dx, float *dy)
{
    *dx = mount->cos_a * sim->pose.heading_cos - mount->sin_a * sim->pose.heading_sin;
    *dy = mount->cos_a * sim->pose.heading_sin + mount->sin_a * sim->pose.heading_cos;
}

/* Distance from (x, y) inside the room along the unit vector (dx, dy) to the nearest wall. */
static float distance_to_wall(const simbase_t *sim, float x, float y, float dx, float dy)
{
    float nearest = 1e9f;
    if (dx > 0.0f) {
        nearest = min_f(nearest, (room_width(sim) - x) / dx);
    } else if (dx < 0.0f) {
        nearest = min_f(nearest, -x / dx);
    }
    if (dy > 0.0f) {
        nearest = min_f(nearest, (room_depth(sim) - y) / dy);
    } else if (dy < 0.0f) {
        nearest = min_f(nearest, -y / dy);
    }
    return max_f(nearest, 0.0f);
}

uint32_t simbase_distance_mm_q16(const simbase_t *sim, uint32_t index)
{
    if (index >= SIMBASE_SENSOR_COUNT) {
        return 0;
    }
    float dx = 0.0f;
    float dy = 0.0f;
    to_room(sim, &sensor_directions[index], &dx, &dy);
    float r = radius(sim);
    float distance = distance_to_wall(sim, sim->pose.x_mm + r * dx, sim->pose.y_mm + r * dy, dx, dy);
    if (distance > (float)sim->config.sensor_range_mm) {
        return 0;
    }
    return (uint32_t)(max_f(distance, MIN_ECHO_MM) * 65536.0f + 0.5f);
}

/* Which beacons light the point (x, y): sectors fanning out from the dock along +x. */
static uint8_t beacons_lighting(const simbase_t *sim, float x, float y)
{
    float ahead = x + DOCK_BEACON_DEPTH_MM;
    float across = y - room_depth(sim) / 2.0f; /* +: the dock's left */
    if (ahead <= 0.0f || ahead * ahead + across * across > BEACON_RANGE_MM * BEACON_RANGE_MM) {
        return 0;
    }
    uint8_t lit = 0;
    if (abs_f(across) <= ahead * MAIN_SECTOR_TAN) {
        lit |= SIMBASE_BEACON_MAIN;
    }
    if (across >= ahead * SIDE_SECTOR_TAN_MIN && across <= ahead * SIDE_SECTOR_TAN_MAX) {
        lit |= SIMBASE_BEACON_LEFT;
    }
    if (-across >= ahead * SIDE_SECTOR_TAN_MIN && -across <= ahead * SIDE_SECTOR_TAN_MAX) {
        lit |= SIMBASE_BEACON_RIGHT;
    }
    return lit;
}

void simbase_probe_beacons(const simbase_t *sim, uint8_t probes[SIMBASE_PROBE_COUNT])
{
    float r = radius(sim);
    for (size_t i = 0; i < SIMBASE_PROBE_COUNT; i++) {
        float dx = 0.0f;
        float dy = 0.0f;
        to_room(sim, &probe_directions[i], &dx, &dy);
        float px = sim->pose.x_mm + r * dx;
        float py = sim->pose.y_mm + r * dy;
        /* The probe sees the beacons only if the dock is inside its field of view. */
        float to_dock_x = -DOCK_BEACON_DEPTH_MM - px;
        float to_dock_y = room_depth(sim) / 2.0f - py;
        float along = to_dock_x * dx + to_dock_y * dy;
        float squared = to_dock_x * to_dock_x + to_dock_y * to_dock_y;
        int in_view = along > 0.0f && along * along >= squared * PROBE_FOV_COS_SQUARED;
        probes[i] = in_view ? beacons_lighting(sim, px, py) : 0u;
    }
}

static int fill_mount(const simbase_t *sim, const mount_direction_t *direction, int32_t z_mm, simbase_mount_t *mount)
{
    float r = radius(sim);
    float x = r * direction->cos_a;
    float y = r * direction->sin_a;
    mount->x_mm = (int32_t)(x >= 0.0f ? x + 0.5f : x - 0.5f);
    mount->y_mm = (int32_t)(y >= 0.0f ? y + 0.5f : y - 0.5f);
    mount->z_mm = z_mm;
    mount->angle_deg = direction->angle_deg;
    return 0;
}

int simbase_sensor_mount(const simbase_t *sim, uint32_t index, simbase_mount_t *mount)
{
    simbase_mount_t none = {0};
    *mount = none;
    if (index >= SIMBASE_SENSOR_COUNT) {
        return -1;
    }
    return fill_mount(sim, &sensor_directions[index], SENSOR_HEIGHT_MM, mount);
}

int simbase_bumper_mount(const simbase_t *sim, uint32_t index, simbase_mount_t *mount)
{
    simbase_mount_t none = {0};
    *mount = none;
    if (index >= SIMBASE_BUMPER_COUNT) {
        return -1;
    }
    return fill_mount(sim, &bumper_directions[index], BUMPER_HEIGHT_MM, mount);
}

int32_t simbase_radius_mm(const simbase_t *sim)
{
    return sim->config.robot_radius_mm;
}
