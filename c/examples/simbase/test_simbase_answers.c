/* SPDX-License-Identifier: MIT */
/* Unit tests of the simulated base's answers (simbase state -> ctrlbus message structs). */
#include <stdio.h>
#include <string.h>

#include "simbase_answers.h"

static int failures;

#define CHECK(cond)                                                                                                    \
    do {                                                                                                               \
        if (!(cond)) {                                                                                                 \
            printf("%s:%d: check failed: %s\n", __FILE__, __LINE__, #cond);                                           \
            failures++;                                                                                                \
        }                                                                                                              \
    } while (0)

static void test_connect(void)
{
    simbase_identity_t identity = {"a model name longer than twelve", 0x0001, 0x0102, {1, 2, 3}, NULL};
    ctrlbus_connect_base_answer_t answer;
    simbase_answer_connect(&identity, &answer);
    CHECK(strcmp(answer.model, "a model name") == 0); /* cut to the 12-byte field */
    CHECK(answer.firmware_version == 0x0001 && answer.hardware_version == 0x0102);
    CHECK(answer.serial[0] == 1 && answer.serial[1] == 2 && answer.serial[2] == 3);
    CHECK(!answer.has_firmware_version_suffix);

    identity.model = "ctrlbus sim";
    identity.firmware_version_suffix = "-sim";
    simbase_answer_connect(&identity, &answer);
    CHECK(strcmp(answer.model, "ctrlbus sim") == 0);
    CHECK(answer.has_firmware_version_suffix && strcmp(answer.firmware_version_suffix, "-sim") == 0);
}

static void test_base_conf(void)
{
    simbase_t sim;
    simbase_init(&sim, NULL);
    ctrlbus_get_base_conf_answer_t conf;
    simbase_answer_base_conf(&sim, &conf);
    CHECK(conf.base_type == 0 && conf.motor_type == 0);
    CHECK(conf.base_radius_mm_q8 == 170u * 256u);
    CHECK(conf.sensor_num == 5 && conf.bumper_num == 2);
    CHECK(conf.sensors[0].x_mm_q8 == 170 * 256 && conf.sensors[0].y_mm_q8 == 0 && conf.sensors[0].angle_deg_q8 == 0);
    CHECK(conf.sensors[2].angle_deg_q8 == 320u * 256u && conf.sensors[2].y_mm_q8 < 0);
    CHECK(conf.sensors[4].angle_deg_q8 == 270u * 256u && conf.sensors[4].y_mm_q8 == -170 * 256);
    CHECK(conf.sensors[0].z_mm_q8 > 0);
    for (size_t i = 5; i < CTRLBUS_CONF_SLOTS; i++) {
        CHECK(conf.sensors[i].x_mm_q8 == 0 && conf.sensors[i].angle_deg_q8 == 0);
    }
    CHECK(conf.bumpers[0].angle_deg_q8 == 45u * 256u && conf.bumpers[1].angle_deg_q8 == 315u * 256u);
    CHECK(conf.bumpers[2].x_mm_q8 == 0);
}

static void test_telemetry(void)
{
    simbase_t sim;
    simbase_init(&sim, NULL);
    ctrlbus_get_base_status_answer_t status;
    simbase_answer_status(&sim, &status);
    CHECK(status.battery_percent == 80 && status.power_status == 0);

    ctrlbus_get_base_bumper_data_answer_t bumpers;
    simbase_answer_bumper_data(&sim, &bumpers);
    CHECK(bumpers.bitmap == 0xFFFFFFFFu && bumpers.payload_size == 4);

    uint8_t probes[SIMBASE_PROBE_COUNT];
    ctrlbus_get_charger_data_answer_t charger;
    simbase_answer_charger_data(&sim, probes, &charger);
    CHECK(charger.beacon_count == 3 && charger.probe_count == 3 && charger.probes == probes);
    CHECK(probes[0] == 0 && probes[1] == SIMBASE_BEACON_MAIN && probes[2] == 0);

    ctrlbus_get_base_sensor_data_answer_t sensors;
    simbase_place(&sim, 3000, 1500, 0);
    simbase_answer_sensor_data(&sim, &sensors);
    CHECK(sensors.distances_mm_q16[0] == 830u * 65536u);
    CHECK(sensors.distances_mm_q16[3] == 1330u * 65536u);
    for (size_t i = SIMBASE_SENSOR_COUNT; i < CTRLBUS_SENSOR_CHANNELS; i++) {
        CHECK(sensors.distances_mm_q16[i] == 0);
    }
}

static void test_commands(void)
{
    simbase_t sim;
    simbase_init(&sim, NULL);
    ctrlbus_set_base_motor_request_t motor = {{-200, -100, 999, 999}};
    simbase_apply_motor(&sim, &motor);
    simbase_step(&sim, 1000);
    ctrlbus_get_base_motor_data_answer_t data;
    simbase_answer_motor_data(&sim, &data);
    /* Backwards: signed totals, the left wheel farther than the right. */
    CHECK(data.left_distance_mm < data.right_distance_mm && data.right_distance_mm < 0);
    CHECK(data.status == 0);

    /* The first 0x41 reports the motion so far; the next one only what came after it. */
    ctrlbus_set_v_and_get_deadreckon_request_t stop = {0, 0, 0};
    ctrlbus_set_v_and_get_deadreckon_answer_t answer;
    simbase_apply_velocity(&sim, &stop, false, 1234, &answer);
    CHECK(answer.dx_mm_q16 < 0 && answer.dtheta_deg_q16 != 0);
    CHECK(!answer.has_timestamp_ms && answer.timestamp_ms == 0);
    simbase_step(&sim, 1000); /* coasting to a stop */
    simbase_apply_velocity(&sim, &stop, true, 5678, &answer);
    CHECK(answer.has_timestamp_ms && answer.timestamp_ms == 5678);
    simbase_step(&sim, 1000);
    simbase_apply_velocity(&sim, &stop, true, 6678, &answer);
    CHECK(answer.dx_mm_q16 == 0 && answer.dy_mm_q16 == 0 && answer.dtheta_deg_q16 == 0);

    /* vx 0.2 m/s, omega 0.5 rad/s with the 118 mm half track: wheels 141 and 259 mm/s. */
    ctrlbus_set_v_and_get_deadreckon_request_t turn = {13107, 0, 32768};
    simbase_apply_velocity(&sim, &turn, false, 0, &answer);
    CHECK(sim.target_left_mm_s == 141.0f && sim.target_right_mm_s == 259.0f);
}

static void test_battery_health(void)
{
    simbase_t sim;
    simbase_config_t config = {0};
    config.battery_start_percent = 30;
    simbase_init(&sim, &config);
    uint32_t code = 0;
    const char *message = NULL;
    CHECK(simbase_battery_health(&sim, &code, &message) == 0);
    sim.battery_micropercent = 29000000;
    CHECK(simbase_battery_health(&sim, &code, &message) == CTRLBUS_HEALTH_WARNING);
    CHECK(code == 0x01020100u && message != NULL && strlen(message) < CTRLBUS_HEALTH_MESSAGE_LEN);
    sim.battery_micropercent = 9000000;
    CHECK(simbase_battery_health(&sim, &code, &message) == CTRLBUS_HEALTH_ERROR);
    CHECK(code == 0x02020100u && message != NULL && strlen(message) < CTRLBUS_HEALTH_MESSAGE_LEN);
}

int main(void)
{
    test_connect();
    test_base_conf();
    test_telemetry();
    test_commands();
    test_battery_health();
    if (failures != 0) {
        printf("test_simbase_answers: %d check(s) failed\n", failures);
        return 1;
    }
    printf("test_simbase_answers: all checks passed\n");
    return 0;
}
