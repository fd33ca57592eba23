/* SPDX-License-Identifier: MIT */
/* The base stack built with CTRLBUS_CONST_IN_FLASH (ctrlbus/ctrlbus_config.h), on the host,
 * where CTRLBUS_READ_CONST is memcpy: GET_BASE_CONF must go out byte for byte as the codec writes
 * it (ctrlbus_get_base_conf_answer_write()), a struct with a count over 8 must be answered 0x8002,
 * and the 0x21 blob must go out as it is. The Uno's minimal base runs the same path from flash
 * (memcpy_P) under QEMU and simavr (python/tests/test_mcu_ports.py). c/CMakeLists.txt builds this
 * file against a copy of the library compiled with the switch (ctest: const_in_flash). */
#include <stdio.h>
#include <string.h>

#include "ctrlbus/base.h"

typedef struct {
    uint8_t bytes[600];
    size_t len;
} capture_t;

static int32_t capture(void *context, const uint8_t *data, size_t size)
{
    capture_t *into = context;
    if (into->len + size > sizeof into->bytes) {
        return CTRLBUS_ERR_IO;
    }
    memcpy(into->bytes + into->len, data, size);
    into->len += size;
    return (int32_t)size;
}

static int failures;

static void check(int ok, const char *what)
{
    if (!ok) {
        printf("FAIL: %s\n", what);
        failures++;
    }
}

/* The answer of the base in `config` to the CTRL_BUS request `code`. */
static capture_t ask(ctrlbus_base_config_t *config, uint8_t code)
{
    static uint8_t rx_ring[64], frame_buffer[64];
    ctrlbus_base_t base;
    capture_t answer = {{0}, 0};
    uint8_t request[8];
    config->rx_ring = rx_ring;
    config->rx_ring_size = sizeof rx_ring;
    config->frame_buffer = frame_buffer;
    config->frame_buffer_size = sizeof frame_buffer;
    config->write = capture;
    config->write_context = &answer;
    int32_t size = ctrlbus_frame_encode(request, sizeof request, CTRLBUS_CMD_CTRL_BUS, &code, 1,
                                        CTRLBUS_FRAME_STANDARD);
    check(size > 0 && ctrlbus_base_init(&base, config, 0) == CTRLBUS_OK, "init");
    check(ctrlbus_base_feed(&base, request, (size_t)size) == (size_t)size, "feed");
    ctrlbus_base_poll(&base, 1);
    return answer;
}

int main(void)
{
    ctrlbus_get_base_conf_answer_t conf;
    memset(&conf, 0, sizeof conf);
    conf.base_type = 1;
    conf.base_radius_mm_q8 = (uint32_t)CTRLBUS_Q8(170);
    conf.motor_type = 0;
    conf.sensor_num = 3;
    conf.bumper_num = 2;
    for (uint8_t i = 0; i < CTRLBUS_CONF_SLOTS; i++) {
        conf.sensors[i].x_mm_q8 = CTRLBUS_Q8(100 + i);
        conf.sensors[i].y_mm_q8 = CTRLBUS_Q8(-20 - i);
        conf.sensors[i].z_mm_q8 = CTRLBUS_Q8(i);
        conf.sensors[i].angle_deg_q8 = (uint32_t)CTRLBUS_Q8(45u * i);
        conf.bumpers[i].x_mm_q8 = CTRLBUS_Q8(150 - i);
        conf.bumpers[i].angle_deg_q8 = (uint32_t)CTRLBUS_Q8(300 + i);
    }
    ctrlbus_base_config_t config;
    memset(&config, 0, sizeof config);
    config.base_conf = &conf;

    capture_t expected = {{0}, 0};
    ctrlbus_sink_t sink;
    check(ctrlbus_sink_init(&sink, capture, &expected) == CTRLBUS_OK, "sink");
    check(ctrlbus_get_base_conf_answer_write(&sink, &conf, CTRLBUS_FRAME_LONG) > 0, "codec");
    capture_t got = ask(&config, CTRLBUS_CODE_GET_BASE_CONF);
    check(got.len == expected.len && got.len > 264u &&
              memcmp(got.bytes, expected.bytes, got.len) == 0,
          "GET_BASE_CONF from const memory is the codec's frame");

    conf.bumper_num = 9;
    got = ask(&config, CTRLBUS_CODE_GET_BASE_CONF);
    static const uint8_t refused[] = {0x50, 0x03, 0x00, CTRLBUS_CMD_ERROR, 0x02, 0x80};
    check(got.len == sizeof refused + 1u && memcmp(got.bytes, refused, sizeof refused) == 0,
          "a count over 8 is answered 0x8002");

    static const uint8_t blob[40] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15, 16, 17, 18,
                                     19, 20, 21, 22, 23, 24, 25, 26, 27, 28, 29, 30, 31, 32, 33, 34};
    config.binary_config = blob;
    config.binary_config_size = sizeof blob;
    got = ask(&config, CTRLBUS_CODE_GET_BASE_CONF_ADV);
    check(got.len == 4u + sizeof blob + 1u && memcmp(got.bytes + 4, blob, sizeof blob) == 0,
          "the 0x21 blob goes out as it is");
    CTRLBUS_CONFIG_CHECK();
    printf("%s\n", failures == 0 ? "const_in_flash: ok" : "const_in_flash: FAILED");
    return failures == 0 ? 0 : 1;
}
