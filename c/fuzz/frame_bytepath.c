/* SPDX-License-Identifier: MIT */
/* frame.c without its bulk path, every public name prefixed bytepath_ (see frame_bytepath.h). A
 * public function added to frame.c needs a line here too (the link fails until it has one). */
#define CTRLBUS_DECODER_FAST 0

#define ctrlbus_buffer_write bytepath_buffer_write
#define ctrlbus_decoder_busy bytepath_decoder_busy
#define ctrlbus_decoder_feed bytepath_decoder_feed
#define ctrlbus_decoder_init bytepath_decoder_init
#define ctrlbus_decoder_next bytepath_decoder_next
#define ctrlbus_decoder_reset bytepath_decoder_reset
#define ctrlbus_decoder_tick bytepath_decoder_tick
#define ctrlbus_error_name bytepath_error_name
#define ctrlbus_frame_encode bytepath_frame_encode
#define ctrlbus_frame_size bytepath_frame_size
#define ctrlbus_frame_write bytepath_frame_write
#define ctrlbus_rx_name bytepath_rx_name
#define ctrlbus_sink_begin bytepath_sink_begin
#define ctrlbus_sink_end bytepath_sink_end
#define ctrlbus_sink_fail bytepath_sink_fail
#define ctrlbus_sink_init bytepath_sink_init
#define ctrlbus_sink_init_buffer bytepath_sink_init_buffer
#define ctrlbus_sink_put bytepath_sink_put
#define ctrlbus_sink_put_s32 bytepath_sink_put_s32
#define ctrlbus_sink_put_text bytepath_sink_put_text
#define ctrlbus_sink_put_u16 bytepath_sink_put_u16
#define ctrlbus_sink_put_u32 bytepath_sink_put_u32
#define ctrlbus_sink_put_u8 bytepath_sink_put_u8

#include "../src/frame.c"
