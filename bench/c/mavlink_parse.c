/* SPDX-License-Identifier: MIT */
/*
 * Benchmark harness for the MAVLink v2 peer: feed a stream file to MAVLink's C parser byte by
 * byte and count the messages, so that callgrind can count the instructions it takes.
 *
 *   mavlink_parse MODE FILE
 *
 * MODE
 *   baseline           read the file and walk its bytes without parsing (the cost subtracted)
 *   parse_char         mavlink_parse_char() on channel 0, as MAVLink's documentation shows
 *   frame_char_buffer  mavlink_frame_char_buffer() with caller-owned buffers (no channel table)
 *
 * Prints "bytes=N messages=M bad_crc=E" so the caller can check the parse was real.
 * Built with gcc -O2 against the headers that mavgen generated from bench/mavlink/ctrlbus_peer.xml.
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

static unsigned long parse_with_parse_char(const unsigned char *data, size_t size, unsigned long *bad)
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

static unsigned long parse_with_frame_char_buffer(const unsigned char *data, size_t size, unsigned long *bad)
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

int main(int argc, char **argv)
{
    if (argc != 3) {
        fprintf(stderr, "usage: %s baseline|parse_char|frame_char_buffer FILE\n", argv[0]);
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
    } else if (strcmp(argv[1], "parse_char") == 0) {
        messages = parse_with_parse_char(data, size, &bad);
    } else if (strcmp(argv[1], "frame_char_buffer") == 0) {
        messages = parse_with_frame_char_buffer(data, size, &bad);
    } else {
        fprintf(stderr, "unknown mode %s\n", argv[1]);
        free(data);
        return 2;
    }
    printf("bytes=%lu messages=%lu bad_crc=%lu\n", (unsigned long)size, messages, bad);
    free(data);
    return 0;
}
