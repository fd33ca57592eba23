/* SPDX-License-Identifier: MIT */
/* A consumer of the ctrlbus library, as a firmware team would write one: it encodes an ECHO frame
 * and decodes it again. Exit status 0 when the round trip gives the frame back and the headers'
 * version is the one the build expects (CONSUMER_EXPECT_VERSION_*); python/tests/test_c_consumers.py
 * builds it through each way of getting the library (CMake subdirectory, FetchContent,
 * find_package, pkg-config, cross build, a wrapping library of the consumer's own).
 * CTRLBUS_CONFIG_CHECK() makes the link fail if the library was built with other switches than
 * this file sees; CONSUMER_EXPECT_HEALTH_OFF checks that consumer_config.h reached the library. */
#include <stddef.h>
#include <stdint.h>

#include "ctrlbus/base.h"
#include "ctrlbus/frame.h"
#include "ctrlbus/messages.h"
#ifdef CONSUMER_USES_ACME
#include "acme_base.h"
#endif

#if defined(CONSUMER_EXPECT_VERSION_MAJOR) &&                                                      \
    (CONSUMER_EXPECT_VERSION_MAJOR != CTRLBUS_VERSION_MAJOR ||                                     \
     CONSUMER_EXPECT_VERSION_MINOR != CTRLBUS_VERSION_MINOR ||                                     \
     CONSUMER_EXPECT_VERSION_PATCH != CTRLBUS_VERSION_PATCH)
#error "the ctrlbus headers found are not the expected version"
#endif

int main(void)
{
    static const uint8_t payload[] = {0x10, 0x01, 0x50};
    uint8_t wire[16], buffer[64];
    ctrlbus_decoder_t decoder;
    ctrlbus_frame_t frame;
    CTRLBUS_CONFIG_CHECK();
#ifdef CONSUMER_EXPECT_HEALTH_OFF
    /* Compiled out, the registry refuses even a NULL base as unsupported (else: an argument error). */
    if (CTRLBUS_CONFIG_HEALTH != 0 || ctrlbus_base_health_add(NULL, 0u, NULL) != CTRLBUS_ERR_UNSUPPORTED) {
        return 4;
    }
#endif
#ifdef CONSUMER_USES_ACME
    if (acme_base_radius_mm_q8() != CTRLBUS_Q8(170)) {
        return 5;
    }
#endif
    int32_t size = ctrlbus_frame_encode(wire, sizeof wire, CTRLBUS_CMD_ECHO, payload,
                                        sizeof payload, CTRLBUS_FRAME_STANDARD);
    if (size <= 0 || ctrlbus_decoder_init(&decoder, buffer, sizeof buffer, 0, NULL) != CTRLBUS_OK) {
        return 1;
    }
    (void)ctrlbus_decoder_feed(&decoder, wire, (size_t)size, 0);
    if (ctrlbus_decoder_next(&decoder, &frame) != CTRLBUS_RX_FRAME || frame.cmd != CTRLBUS_CMD_ECHO ||
        frame.payload_len != sizeof payload) {
        return 2;
    }
    for (size_t i = 0; i < sizeof payload; i++) {
        if (frame.payload[i] != payload[i]) {
            return 3;
        }
    }
    return 0;
}
