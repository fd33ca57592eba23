/* SPDX-License-Identifier: MIT */
/* ctrlbus_base_missing_handlers(): which of the 13 mandatory requests' handlers a config lacks
 * (ctrlbus/base.h), and the fixed-point helpers of ctrlbus/ctrlbus.h. */
#include <stdint.h>

#include "ctrlbus/base.h"
#include "harness.h"

static int32_t write_nothing(void *context, const uint8_t *data, size_t size)
{
    (void)context, (void)data, (void)size;
    return CTRLBUS_OK;
}

static int32_t connect_info(void *context, ctrlbus_connect_base_answer_t *out)
{
    (void)context, (void)out;
    return CTRLBUS_OK;
}

static int32_t set_wheel_speeds(void *context, int32_t left_mm_s, int32_t right_mm_s)
{
    (void)context, (void)left_mm_s, (void)right_mm_s;
    return CTRLBUS_OK;
}

static void test_missing_handlers_are_named(void)
{
    static uint8_t rx_ring[16], frame_buffer[64];
    static const ctrlbus_get_base_conf_answer_t conf = {0};
    ctrlbus_base_t base;
    ctrlbus_base_config_t config = {0};
    config.rx_ring = rx_ring;
    config.rx_ring_size = sizeof rx_ring;
    config.frame_buffer = frame_buffer;
    config.frame_buffer_size = sizeof frame_buffer;
    config.write = write_nothing;
    CHECK_EQ(ctrlbus_base_missing_handlers(NULL), 0);
    CHECK_EQ(ctrlbus_base_init(&base, &config, 0), CTRLBUS_OK); /* accepted, but: */
    CHECK_EQ(ctrlbus_base_missing_handlers(&base), 0x1FF);
    config.connect_info = connect_info;
    config.base_conf = &conf;
    config.set_wheel_speeds = set_wheel_speeds;
    CHECK_EQ(ctrlbus_base_missing_handlers(&base),
             CTRLBUS_BASE_NEEDS_STATUS | CTRLBUS_BASE_NEEDS_MOTOR_DATA |
                 CTRLBUS_BASE_NEEDS_SENSOR_DATA | CTRLBUS_BASE_NEEDS_BUMPER_DATA |
                 CTRLBUS_BASE_NEEDS_CHARGER_DATA | CTRLBUS_BASE_NEEDS_SET_VELOCITY);
}

static void test_fixed_point_helpers_are_32_bit(void)
{
    /* 170 << 8 overflows a 16-bit int; the helpers compute in int32_t. */
    CHECK_EQ(CTRLBUS_Q8(170), 43520);
    CHECK_EQ(CTRLBUS_Q16(-2), -131072);
    CHECK_EQ(CTRLBUS_Q16(32767), 2147418112LL);
    CHECK_EQ(CTRLBUS_FROM_Q8(CTRLBUS_Q8(-170)), -170);
    CHECK_EQ(CTRLBUS_FROM_Q16(CTRLBUS_Q16(1) + 65535), 1);
    CHECK_EQ(CTRLBUS_FROM_Q16(-65537), -1); /* toward zero */
    CHECK_EQ((long long)sizeof(CTRLBUS_Q8(1)), 4);
}

int main(void)
{
    RUN(test_missing_handlers_are_named);
    RUN(test_fixed_point_helpers_are_32_bit);
    return harness_finish();
}
