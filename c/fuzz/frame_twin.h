/* SPDX-License-Identifier: MIT */
/* Included by a file that builds frame.c once more under other names (frame_bytepath.c,
 * frame_lean.c): every public name of frame.c gets the prefix TWIN_PREFIX (defined by the
 * includer, with the CTRLBUS_DECODER_FAST level it tests). A public function added to frame.c
 * needs a line here too (the link fails until it has one). */
#define TWIN_PASTE(prefix, name) prefix##name
#define TWIN_NAME(prefix, name) TWIN_PASTE(prefix, name)
#define TWIN(name) TWIN_NAME(TWIN_PREFIX, name)

#define ctrlbus_buffer_write TWIN(buffer_write)
#define ctrlbus_decoder_busy TWIN(decoder_busy)
#define ctrlbus_decoder_feed TWIN(decoder_feed)
#define ctrlbus_decoder_init TWIN(decoder_init)
#define ctrlbus_decoder_next TWIN(decoder_next)
#define ctrlbus_decoder_push TWIN(decoder_push_inline)
#define ctrlbus_decoder_push_slow TWIN(decoder_push_slow)
#define ctrlbus_decoder_reset TWIN(decoder_reset)
#define ctrlbus_decoder_take TWIN(decoder_take_inline)
#define ctrlbus_decoder_take_slow TWIN(decoder_take_slow)
#define ctrlbus_decoder_tick TWIN(decoder_tick)
#define ctrlbus_error_name TWIN(error_name)
#define ctrlbus_frame_encode TWIN(frame_encode)
#define ctrlbus_frame_size TWIN(frame_size)
#define ctrlbus_frame_write TWIN(frame_write)
#define ctrlbus_rx_name TWIN(rx_name)
#define ctrlbus_sink_begin TWIN(sink_begin)
#define ctrlbus_sink_emit TWIN(sink_emit)
#define ctrlbus_sink_end TWIN(sink_end)
#define ctrlbus_sink_fail TWIN(sink_fail)
#define ctrlbus_sink_finish TWIN(sink_finish)
#define ctrlbus_sink_init TWIN(sink_init)
#define ctrlbus_sink_init_buffer TWIN(sink_init_buffer)
#define ctrlbus_sink_put TWIN(sink_put)
#define ctrlbus_sink_put_s32 TWIN(sink_put_s32)
#define ctrlbus_sink_put_text TWIN(sink_put_text)
#define ctrlbus_sink_put_u16 TWIN(sink_put_u16)
#define ctrlbus_sink_put_u32 TWIN(sink_put_u32)
#define ctrlbus_sink_put_u8 TWIN(sink_put_u8)
#define ctrlbus_sink_start TWIN(sink_start)

#include "../src/frame.c"

/* frame.h's static inline push, renamed above, called from outside this file. */
ctrlbus_rx_t TWIN(decoder_push)(ctrlbus_decoder_t *decoder, uint8_t byte, uint32_t now_ms,
                                ctrlbus_frame_t *frame);
ctrlbus_rx_t TWIN(decoder_push)(ctrlbus_decoder_t *decoder, uint8_t byte, uint32_t now_ms,
                                ctrlbus_frame_t *frame)
{
    return TWIN(decoder_push_inline)(decoder, byte, now_ms, frame);
}

/* frame.h's static inline take, likewise. */
ctrlbus_rx_t TWIN(decoder_take)(ctrlbus_decoder_t *decoder, const uint8_t **data, size_t *len,
                                uint32_t now_ms, ctrlbus_frame_t *frame);
ctrlbus_rx_t TWIN(decoder_take)(ctrlbus_decoder_t *decoder, const uint8_t **data, size_t *len,
                                uint32_t now_ms, ctrlbus_frame_t *frame)
{
    return TWIN(decoder_take_inline)(decoder, data, len, now_ms, frame);
}
