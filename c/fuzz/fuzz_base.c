/* SPDX-License-Identifier: MIT */
/* Fuzz target: the whole base stack (ctrlbus/base.h) on arbitrary bytes: bytes in through the
 * receive ring, answers out through the write callback, every answer checked by the oracle of
 * base_harness.h (it must be a valid frame, and the right answer to the right request or event).
 *
 * Input: the four setting bytes of base_harness.h; one byte that says how the stream is cut into
 * feeds (bits 0-1: 1-8, 1-64 or 1-600 bytes, or whole) and seeds the time between polls (none,
 * 1 ms, up to and past the inter-byte timeout, past the watchdog) and whether a poll follows each
 * feed; then the stream, as it would come off the UART. */
#include "base_harness.h"
#include "fuzz_common.h"

static const uint32_t CUT_MAX[4] = {8, 64, 600, 0}; /* 0: the whole stream in one feed */

static uint32_t time_step(fuzz_rng_t *rng)
{
    uint32_t timeout = base_harness_timeout_ms();
    switch (fuzz_rng_below(rng, 12)) {
    case 0: return 1;
    case 1: return timeout;
    case 2: return timeout + 1u;
    case 3: return base_harness_watchdog_ms() + 1u;
    default: return 0;
    }
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size)
{
    fuzz_input_t in = {data, size};
    uint32_t now = 0xFFFFF000u; /* the clock wraps around during the run */
    base_harness_start(&in, now);
    uint8_t style = fuzz_u8(&in);
    fuzz_rng_t rng;
    fuzz_rng_seed(&rng, style);
    uint32_t cut_max = CUT_MAX[style & 3u];
    const uint8_t *stream = in.data;
    size_t len = in.left;
    for (size_t pos = 0; pos < len;) {
        size_t cut = len - pos;
        if (cut_max != 0 && cut > 1) {
            size_t most = cut < cut_max ? cut : cut_max;
            cut = 1u + fuzz_rng_below(&rng, (uint32_t)most);
        }
        base_harness_feed(stream + pos, cut, now);
        pos += cut;
        if (fuzz_rng_below(&rng, 3) != 0) {
            base_harness_poll(now);
        }
        now += time_step(&rng);
    }
    base_harness_finish(now);
    return 0;
}
