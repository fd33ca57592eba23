/* SPDX-License-Identifier: MIT */
/*
 * Benchmark harness for the MAVLink v2 peer: feed a stream file to MAVLink's C parser byte by
 * byte and count the messages, so that callgrind can count the instructions it takes.
 *
 *   mavlink_parse MODE FILE
 *
 * MODE
 *   baseline  read the file and walk its bytes without parsing (the cost subtracted)
 *   parse     the parser API this binary was built for, one call per byte
 *
 * The API is chosen when compiling, so that the binary calls MAVLink from exactly one place, as a
 * MAVLink user's receive loop does: MAVLink's parser functions are `static inline` in its headers,
 * and a second call site (another API, or the same one twice) makes gcc keep them out of line,
 * which adds a call and the copies of the status structs to every byte. Earlier versions of this
 * harness did that and reported about 2.6 times MAVLink's real cost.
 *   (default)                   mavlink_parse_char() on channel 0, as MAVLink's documentation shows
 *   -DPEER_FRAME_CHAR_BUFFER    mavlink_frame_char_buffer() with caller-owned buffers (no channel table)
 *
 * Prints "bytes=N messages=M bad_crc=E" so the caller can check the parse was real.
 * Built against the headers that mavgen generated from bench/mavlink/ctrlbus_peer.xml, with the
 * flags bench/callgrind.py records in the result (gcc -O2, and -Os as firmware is built).
 */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "read_file.h"

#include "ctrlbus_peer/mavlink.h"

/* The same walk over the bytes as the parsing loops, with the parser call replaced by a store
 * the compiler cannot drop. */
static unsigned long walk_bytes(const unsigned char *data, size_t size)
{
    volatile unsigned char sink = 0;
    for (size_t i = 0; i < size; i++) {
        sink = data[i];
    }
    return (unsigned long)sink * 0u;
}

#ifndef PEER_FRAME_CHAR_BUFFER
static unsigned long parse(const unsigned char *data, size_t size, unsigned long *bad)
{
    mavlink_message_t msg;
    mavlink_status_t status;
    unsigned long messages = 0;
    memset(&status, 0, sizeof status);
    for (size_t i = 0; i < size; i++) {
        if (mavlink_parse_char(MAVLINK_COMM_0, data[i], &msg, &status) == MAVLINK_FRAMING_OK) {
            messages++;
        }
    }
    *bad = mavlink_get_channel_status(MAVLINK_COMM_0)->packet_rx_drop_count;
    return messages;
}
#else
static unsigned long parse(const unsigned char *data, size_t size, unsigned long *bad)
{
    mavlink_message_t rx, msg;
    mavlink_status_t rx_status, status;
    unsigned long messages = 0;
    memset(&rx, 0, sizeof rx);
    memset(&rx_status, 0, sizeof rx_status);
    *bad = 0;
    for (size_t i = 0; i < size; i++) {
        uint8_t result = mavlink_frame_char_buffer(&rx, &rx_status, data[i], &msg, &status);
        if (result == MAVLINK_FRAMING_OK) {
            messages++;
        } else if (result == MAVLINK_FRAMING_BAD_CRC) {
            (*bad)++;
        }
    }
    return messages;
}
#endif

int main(int argc, char **argv)
{
    if (argc != 3) {
        fprintf(stderr, "usage: %s baseline|parse FILE\n", argv[0]);
        return 2;
    }
    size_t size = 0;
    unsigned char *data = read_file(argv[2], &size);
    if (data == NULL) {
        return 2;
    }
    unsigned long messages = 0, bad = 0;
    if (strcmp(argv[1], "baseline") == 0) {
        messages = walk_bytes(data, size);
    } else if (strcmp(argv[1], "parse") == 0) {
        messages = parse(data, size, &bad);
    } else {
        fprintf(stderr, "unknown mode %s\n", argv[1]);
        free(data);
        return 2;
    }
    printf("bytes=%lu messages=%lu bad_crc=%lu\n", (unsigned long)size, messages, bad);
    free(data);
    return 0;
}
