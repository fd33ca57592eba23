/* SPDX-License-Identifier: MIT */
/* The base stack (ctrlbus/base.h) under fuzzing, with an oracle for what it answers. Shared by
 * fuzz_base.c (raw bytes) and fuzz_fixup.c (frames with their lengths and checksums fixed up).
 *
 * The harness builds a base from four setting bytes of the input, with handlers that give varied,
 * valid answers (and, if asked, fail at random or hand back structs the codecs refuse). It feeds
 * bytes through ctrlbus_base_feed() and calls ctrlbus_base_poll(), exactly as a firmware's UART
 * interrupt and main loop would. After every poll it checks:
 *   - no write outside the ring and the frame buffer (guard regions; ASan poisons them);
 *   - everything written is whole, valid frames (our own decoder reads them back, and finds no
 *     garbage, no bad checksum and no partial frame), each an answer (SYNC, ECHO, OK or ERROR) of
 *     the frame type the settings ask for;
 *   - the answers match the requests one to one, in stream order. A shadow decoder with the same
 *     settings gets the same bytes at the same times (the base stamps bytes with the time of the
 *     poll that takes them), so it knows every frame and event the base's decoder saw: SYNC and
 *     ECHO come back verbatim; an event gets its ERROR code (§8.1: garbage 0x0010, checksum 0x0040
 *     or 0x00C0, oversize 0x0020, empty frame 0x8001; a timeout nothing); a request that
 *     ctrlbus_request_decode() refuses gets ERROR ctrlbus_request_error_code(); any other request
 *     an OK answer that ctrlbus_answer_decode() reads as the answer to that request (with the
 *     profile's sizes), or ERROR 0x8000 / 0x8002;
 *   - with velocity limits set, no motion command outside them reaches the handlers;
 *   - a REBOOT answered OK is the last thing the poll writes, and the base then starts afresh.
 *
 * Setting bytes (the first four of the input):
 *   byte 0  bits 0-2: frame_buffer_size 5, 16, 64, 300, 512, 512, 1024 or 65539;
 *           bits 3-4: answers: reference profile in long frames; reference with standard_answers;
 *                     sdk2020; reference with reference_checksum_code;
 *           bit 5: velocity limits; bit 6: handlers fail now and then; bit 7: an 8-byte ring
 *           (else 1024 bytes), so that it fills up and drops bytes.
 *   byte 1  bits 0-1: frame_timeout_ms default (10), off, 1 or 50;
 *           bits 2-3: watchdog_ms default (1000), off, 5 or 100;
 *           bit 4: storage for health entries and the command queue; bit 5: a binary config;
 *           bit 6: reboot and enter_dfu handlers; bit 7: a stop_motors handler.
 *   bytes 2-3: the seed of the handlers' values and failures. */
#ifndef CTRLBUS_FUZZ_BASE_HARNESS_H
#define CTRLBUS_FUZZ_BASE_HARNESS_H

#include <stddef.h>
#include <stdint.h>

#include "fuzz_common.h"

/* Reads the four setting bytes and starts a base at time now_ms. */
void base_harness_start(fuzz_input_t *in, uint32_t now_ms);

/* Puts bytes into the base's ring as a UART interrupt would; when the ring is full it polls at
 * now_ms (as a host reader thread waits for room), so no byte is lost. */
void base_harness_feed(const uint8_t *data, size_t len, uint32_t now_ms);

/* A main-loop poll at now_ms, then every check above. */
void base_harness_poll(uint32_t now_ms);

/* Offers an external command (ctrlbus_base_queue_command()), as the application would. */
void base_harness_queue_command(uint8_t code);

/* The base's inter-byte timeout and watchdog period in ms (0: off). */
uint32_t base_harness_timeout_ms(void);
uint32_t base_harness_watchdog_ms(void);

/* Polls once more, and again long after the line went quiet (every partial request timed out,
 * the watchdog run), with the same checks. */
void base_harness_finish(uint32_t now_ms);

#endif
