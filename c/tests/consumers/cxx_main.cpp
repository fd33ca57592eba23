// SPDX-License-Identifier: MIT
// The public headers from C++ before C++20 (python/tests/test_c_consumers.py builds it with
// -std=c++11 and -std=c++17): every header included, a base configured the C++ way (no designated
// initializers), the fixed-point helpers, and the link against the C library.
#include <cstdint>

#include "ctrlbus/base.h"
#include "ctrlbus/ctrlbus.h"
#include "ctrlbus/ctrlbus_config.h"
#include "ctrlbus/diffdrive.h"
#include "ctrlbus/frame.h"
#include "ctrlbus/messages.h"

static int32_t write_nothing(void *, const uint8_t *, size_t) { return CTRLBUS_OK; }

int main()
{
    static uint8_t rx_ring[64], frame_buffer[64];
    static ctrlbus_base_t base;
    ctrlbus_base_config_t config = {};
    config.rx_ring = rx_ring;
    config.rx_ring_size = sizeof rx_ring;
    config.frame_buffer = frame_buffer;
    config.frame_buffer_size = sizeof frame_buffer;
    config.write = write_nothing;
    CTRLBUS_CONFIG_CHECK();
    if (ctrlbus_base_init(&base, &config, 0) != CTRLBUS_OK) {
        return 1;
    }
    static_assert(CTRLBUS_Q8(170) == 43520 && CTRLBUS_FROM_Q16(CTRLBUS_Q16(-3)) == -3, "fixed point");
    return CTRLBUS_Q16(1) == 65536 ? 0 : 2;
}
