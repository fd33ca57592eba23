/* SPDX-License-Identifier: MIT */
/* ctrlbus base stack: the slave side of the SLAMWARE Control Bus, for a robot base's firmware.
 *
 * What it does: it takes the bytes the UART receives, finds the requests in them (frame.h's
 * decoder: inter-byte timeout, backtracking), answers every one (messages.h's codecs), and keeps
 * the motor safe (the watchdog, optional velocity limits). The application supplies what the
 * robot knows and does, through callbacks; the stack does the protocol (docs/protocol.md), the
 * same way as the Python base framework (ctrlbus.base, docs/base-framework.md).
 *
 *     static uint8_t rx_ring[256], frame_buffer[512];
 *     static const ctrlbus_base_config_t config = {
 *         .rx_ring = rx_ring, .rx_ring_size = sizeof rx_ring,
 *         .frame_buffer = frame_buffer, .frame_buffer_size = sizeof frame_buffer,
 *         .write = uart_write, .connect_info = my_connect_info, .status = my_status, ...};
 *     static ctrlbus_base_t base;
 *
 *     ctrlbus_base_init(&base, &config, millis());   // before the UART interrupt is enabled
 *     void uart_rx_isr(void) { (void)ctrlbus_base_feed_byte(&base, UART->DATA); }
 *     for (;;) { ctrlbus_base_poll(&base, millis()); sleep_until_interrupt(); }
 *
 * Input: ctrlbus_base_feed_byte() (one byte) and ctrlbus_base_feed() (a run of them) put received
 * bytes into a single-producer/single-consumer ring over the caller's rx_ring array; they are
 * meant for the UART interrupt (see "Concurrency" below). The
 * main loop calls ctrlbus_base_poll(), which moves the ring's bytes through the decoder, answers
 * each request and runs the motor watchdog.
 *
 * Output: answers are streamed through config->write with a running checksum (frame.h's sink),
 * field by field, straight from the application's answer struct or, for GET_BASE_CONF_ADV, from
 * the caller's constant blob. There is NO transmit buffer, and no path needs one: SYNC and ECHO
 * answers are written from the decoder's frame buffer, where the request still is. The write
 * callback receives pieces (a header, a run of integer fields straight from the answer struct,
 * a text field one byte at a time, the checksum) and must take all of them: a blocking UART write (wait for room in the transmit
 * register) is the simplest. Note that a blocking write holds
 * the main loop for the answer's time on the wire (23 ms for GET_BASE_CONF at 115200 baud);
 * received bytes keep arriving in the ring meanwhile, which must be large enough for them (a Core
 * sends its next request only after the answer, so a few dozen bytes are plenty; 256 is ample).
 *
 * Handlers: one callback per request (connect_info, status, ...; GET_BASE_CONF is answered from
 * the application's struct config->base_conf instead, so its 264 bytes never sit on the stack).
 * Each fills the answer struct of messages.h that the stack passes in (zeroed first) and returns
 * CTRLBUS_OK; any negative value makes the answer ERROR 0x8002 (operation failed), except
 * CTRLBUS_ERR_UNSUPPORTED, which answers 0x8000. A NULL handler means "not supported": the request is answered 0x8000, as
 * the protocol prescribes (docs/protocol.md §8.2 check 8). The stack has already validated the
 * request (length, argument values) and applied the velocity limits when a handler runs. Handlers
 * run inside ctrlbus_base_poll(), in the main loop; they may call the health and command-queue
 * functions below, but never ctrlbus_base_poll() itself.
 *
 * Concurrency and memory ordering. ctrlbus_base_feed() and ctrlbus_base_feed_byte() are the only
 * functions that may run in an interrupt (or another thread); everything else belongs to the main loop, one context. The ring
 * has two indices, each written by one side only: rx_head by feed, rx_tail by poll. Both are
 * volatile, so the compiler neither caches them nor drops their stores, and a fence (the macro
 * CTRLBUS_RING_FENCE, below) orders the ring's data against them: feed writes the bytes, fences,
 * then publishes rx_head; poll reads rx_head, fences, reads the bytes, fences, then publishes
 * rx_tail. Requirements:
 *   - the CPU must load and store a uint16_t index in one access. True for every 16- and 32-bit
 *     MCU. On an 8-bit MCU keep rx_ring_size <= 256, so that an index fits in its low byte and a
 *     torn read of the always-zero high byte is harmless;
 *   - on a single-core MCU (Cortex-M0/M3/M4/M7 and the like) an interrupt sees the main loop's
 *     memory in program order; the fence then only has to stop the compiler from moving memory
 *     accesses across it;
 *   - on a multi-core host (a reader thread feeding, the main thread polling) the fence must also
 *     order the hardware: a full barrier.
 * With GCC and Clang, CTRLBUS_RING_FENCE() defaults to __sync_synchronize(), a full barrier for
 * compiler and hardware (one DMB instruction on a Cortex-M, MFENCE on x86), right for both cases.
 * With another compiler it defaults to nothing: define it when compiling the library (at least a
 * compiler barrier on a single core, a full barrier on several). C99 has no atomics; this
 * volatile-plus-fence scheme is the portable substitute, and a ring index is never written by two
 * contexts, so no read-modify-write needs to be atomic.
 *
 * Time: now_ms is a free-running millisecond clock (it may wrap at 2^32, must not run backwards,
 * and poll must be called at least once every 2^31 ms). Bytes are stamped with the time of the
 * poll that takes them from the ring, so the inter-byte timeout and the watchdog have the poll
 * period as their resolution: poll every few milliseconds, and at least every frame_timeout_ms / 2
 * (a main loop stalled longer than the frame timeout while a request is arriving can time that
 * request out; the Core then sends it again).
 *
 * Footprint: ctrlbus_base_t holds only the stack's own state (the ring indices, the decoder, the
 * watchdog's time, the counters), besides the caller's rx_ring, frame_buffer and the optional
 * health and command storage; nothing is allocated. ctrlbus_base_poll() needs a bounded C stack,
 * plus what the handlers and write use: the storage of the answer a handler fills (as large as
 * GET_BASE_SENSOR_DATA's 64 bytes, the largest; GET_BASE_CONF and the 0x21 blob are written from
 * the application's storage) is on the stack while a handler runs or the answer is written, the
 * frame writer only while the answer is written. `make size` prints the sizes and the worst stack
 * per target and configuration, and docs/performance.md tables them (figures, not contracts).
 * Features can be compiled out (ctrlbus/ctrlbus_config.h).
 *
 * Behaviour: what the stack does by itself (docs/protocol.md has the wire rules it follows):
 *  1. Order. ctrlbus_base_poll() runs the motor watchdog (6), then takes the bytes that were in
 *     the ring when it started through the stream decoder (docs/protocol.md §7; the largest frame
 *     is frame_buffer_size, the inter-byte timeout frame_timeout_ms), and writes one answer per
 *     request or decoder event, in stream order, before it returns.
 *  2. Decoder events. Bytes outside any frame: ERROR 0x0010, once per garbage gap. A frame longer
 *     than frame_buffer: 0x0020, as soon as its header announces it. A checksum mismatch: 0x0040
 *     (0x00C0 with reference_checksum_code), and the frame is never executed. An empty frame
 *     (LEN 0): 0x8001. A frame cut by the inter-byte timeout: no answer.
 *  3. SYNC and ECHO: answered with a byte-for-byte copy of the request frame (its flag kept),
 *     written from the frame buffer, any size up to frame_buffer_size. No handler runs; they do
 *     not feed the watchdog.
 *  4. Validation, in this order, before any handler runs: an unknown CMD (answer CMDs included):
 *     0x8000; CTRL_BUS without a request code: 0x8001; an unknown request code: 0x8000;
 *     HEALTH_MGMT without a sub-command: 0x8001, with an unknown one: 0x8002; a wrong payload
 *     length for the request: 0x8001 (the reference does not check lengths; ctrlbus does, because
 *     a short SET_BASE_MOTOR would otherwise move a wheel on bytes nobody sent); CONNECT_BASE
 *     version other than 1, GET_CHARGER_DATA type other than 0, BASE_CMD sub-command other than 1
 *     or 2: 0x8000; GET_AUXILIARY_ANCHOR (0x35): always 0x8000; a NULL handler: 0x8000.
 *  5. Handler results (see "Handlers" above): CTRLBUS_OK sends OK with the struct the handler
 *     filled, once the codec has accepted it; a struct it refuses (text that is not ASCII, a
 *     count over 8, ...) is a failure found before any byte goes out: 0x8002.
 *     CTRLBUS_ERR_UNSUPPORTED sends 0x8000, any other negative value 0x8002. The stack carries on
 *     with the next request.
 *  6. Motor watchdog. Every CTRL_BUS frame that passes its checksum feeds it, even one that is
 *     then refused; SYNC, ECHO and BASE_CMD do not. It is armed at ctrlbus_base_init(). At the
 *     first poll more than watchdog_ms after the last feed it calls stop_motors (default:
 *     set_wheel_speeds(context, 0, 0)), once per silence. If the last motion command handed to
 *     the application was not zero (a wheel speed, or vx, vy or omega), that stop is a trip:
 *     counted in watchdog_trips, and the health warning CTRLBUS_HEALTH_WATCHDOG_TRIPPED is
 *     registered, where it stays until the Core clears it.
 *  7. Velocity limits (config->limits, ctrlbus_base_limits_t): applied before the handler runs,
 *     counted in clamped_commands, still answered OK.
 *  8. Requests answered by the stack alone: POLL_BASE_CMD / POLL_BASE_ANS_CMD from the command
 *     queue (ctrlbus_base_queue_command(); the oldest command until the Core takes it; nothing
 *     pending: per the profile); HEALTH_MGMT from the health registry (GET_HEALTH: the OR of the
 *     entries' level bits and their count; GET_ERROR of an index out of range and CLR_ERROR of a
 *     code not registered: 0x8002); SEND_EVENT: OK for every code, after on_event if given;
 *     BASE_CMD REBOOT / ENTER_DFU: OK when the hook is given, which runs once the answer is out.
 *  9. Answers: OK and ERROR in long frames (0x50) as the reference sends them, unless
 *     standard_answers; answer sizes per the profile (ctrlbus_base_profile_t).
 *
 * What the application does:
 *   - the platform: ctrlbus_base_feed_byte() from the UART receive interrupt, ctrlbus_base_poll()
 *     from the main loop every few milliseconds with a millisecond clock, and a write callback
 *     that takes every byte (c/examples/minimal_base/ is a complete base in one file);
 *   - per request, one handler filling the answer struct with what the robot knows. The 13
 *     requests every base must answer (docs/protocol.md §5) need connect_info, base_conf (the
 *     GET_BASE_CONF answer itself, a struct the application keeps), status, motor_data,
 *     sensor_data, bumper_data, charger_data, set_wheel_speeds and set_velocity; POLL_BASE_CMD, POLL_BASE_ANS_CMD, SEND_EVENT and HEALTH_MGMT need none;
 *   - the robot itself: driving and stopping the motors, odometry (the wheel totals of
 *     motor_data, the deadreckon deltas of set_velocity: ctrlbus/diffdrive.h helps), the local
 *     bumper safety and stall detection, and the robot's own health conditions (battery, motors,
 *     sensors), registered and cleared with ctrlbus_base_health_add() / _clear().
 * The Python stack (ctrlbus.base) behaves the same, in these forms: time in integer milliseconds;
 * the watchdog acts at the first poll after its deadline; the BASE_CMD hooks run right after the
 * answer was written; the health list and command queue hold what the caller's storage holds;
 * the counters are ctrlbus_base_counters_t and the decoder's.
 */
#ifndef CTRLBUS_BASE_H
#define CTRLBUS_BASE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#include "ctrlbus/ctrlbus.h"
#include "ctrlbus/frame.h"
#include "ctrlbus/messages.h"

#ifdef __cplusplus
extern "C" {
#endif

/* The ring's memory fence (see "Concurrency" above). Override it with -DCTRLBUS_RING_FENCE()=...
 * when compiling the library. */
#ifndef CTRLBUS_RING_FENCE
#if defined(__GNUC__) || defined(__clang__)
#define CTRLBUS_RING_FENCE() __sync_synchronize()
#else
#define CTRLBUS_RING_FENCE() ((void)0)
#endif
#endif

/* Defaults and special values of the configuration. */
#define CTRLBUS_BASE_DEFAULT_WATCHDOG_MS 1000u /* the reference's motor watchdog */
#define CTRLBUS_BASE_WATCHDOG_OFF 0xFFFFFFFFu  /* watchdog_ms: no motor watchdog */
#define CTRLBUS_BASE_TIMEOUT_OFF 0xFFFFu       /* frame_timeout_ms: no inter-byte timeout */
#define CTRLBUS_BASE_RX_RING_MAX 65535u        /* largest rx_ring_size */
/* The frame buffer the reference base has; the recommended frame_buffer_size. */
#define CTRLBUS_BASE_FRAME_BUFFER_RECOMMENDED 512u

/* The health warning the motor watchdog registers (docs/protocol.md §10.3): level 1 warning,
 * component 3 motion, type 0x80 (ctrlbus's own), index 0. */
#define CTRLBUS_HEALTH_WATCHDOG_TRIPPED 0x01038000u
#define CTRLBUS_HEALTH_WATCHDOG_TRIPPED_MESSAGE "motor watchdog tripped"

/* Which answer variants the base sends where the sources know two (docs/protocol.md §6.2). */
typedef enum {
    /* The 2018/v4 reference firmware: CONNECT 28 bytes, deadreckon 13 bytes, POLL_BASE_CMD with
     * nothing pending answered OK with an empty payload. */
    CTRLBUS_PROFILE_REFERENCE = 0,
    /* What the vendor's 2020 master SDK reads: CONNECT 39 bytes (the suffix is added, empty, if
     * the handler gives none), deadreckon 17 bytes (timestamp_ms is filled in with the
     * milliseconds since ctrlbus_base_init() or the last reboot if the handler leaves it out),
     * bumpers always 4 bytes, POLL_BASE_CMD with nothing pending answered `FF 00`. Needs long
     * answers (that master checks for the 0x50 flag). */
    CTRLBUS_PROFILE_SDK2020 = 1
} ctrlbus_base_profile_t;

/* CTRLBUS_DEFAULT_PROFILE (ctrlbus_config.h) is the profile a config whose `profile` is left zero
 * gets. */

/* Optional limits on what the Core may command (docs/protocol.md §9.2); 0 means no limit.
 * Commands beyond them are limited, counted (ctrlbus_base_counters_t.clamped_commands) and still
 * answered OK; the handlers only ever see the limited values. */
typedef struct {
    /* SET_BASE_MOTOR: if either wheel is faster than this (mm/s), both are scaled by the same
     * factor so that the faster one is at the limit (the path keeps its curvature). Also applied
     * to SET_V_AND_GET_DEADRECKON when wheel_track_mm is set: vx and omega are then scaled
     * together so that the wheel speeds they give stay within it. */
    uint16_t max_wheel_mm_s;
    /* The distance between the wheels (mm), to turn (vx, omega) into wheel speeds for the wheel
     * limit; 0: SET_V_AND_GET_DEADRECKON gets only the two limits below. */
    uint16_t wheel_track_mm;
    /* SET_V_AND_GET_DEADRECKON: |vx| (m/s Q16) and |omega| (rad/s Q16), each clamped on its own
     * before the wheel limit. vy is passed on unchanged (a differential base ignores it). */
    uint32_t max_vx_mps_q16;
    uint32_t max_omega_radps_q16;
} ctrlbus_base_limits_t;

/* One entry of the health registry (caller-owned storage, see the config). */
typedef struct {
    uint32_t code;       /* CTRLBUS_HEALTH_CODE(level, component, type, index) */
    const char *message; /* at most 31 ASCII characters; must outlive the entry */
} ctrlbus_base_health_entry_t;

/* Everything the stack is given. Caller-owned; it must stay valid and unchanged while the base
 * runs (ctrlbus_base_t keeps a pointer to it). Zero or NULL in a field means its default, or for
 * a handler "not supported" (the request is answered ERROR 0x8000). */
typedef struct {
    /* ---- buffers (caller-owned) ---------------------------------------------------------- */
    /* Required. The receive ring that ctrlbus_base_feed() fills: 2..65535 bytes, holds one byte
     * less than its size. It only has to hold what arrives between two polls. */
    uint8_t *rx_ring;
    uint16_t rx_ring_size;
    /* Required. The decoder's buffer: its size is the largest request frame accepted, header and
     * checksum included (5..65539; CTRLBUS_BASE_FRAME_BUFFER_RECOMMENDED is the reference's 512).
     * A longer request is answered ERROR 0x0020. */
    uint8_t *frame_buffer;
    size_t frame_buffer_size;
    /* The health registry's storage (health_capacity entries, at most 255). NULL: the registry
     * can hold only the motor watchdog's warning, and ctrlbus_base_health_add() refuses other
     * codes. */
    ctrlbus_base_health_entry_t *health_entries;
    uint8_t health_capacity;
    /* The external-command queue's storage (command_queue_size codes, at most 255). NULL: one
     * pending command at a time. */
    uint8_t *command_queue;
    uint8_t command_queue_size;
    /* GET_BASE_CONF_ADV: the binary configuration blob, streamed from here (so it may live in
     * flash; on AVR, PROGMEM with CTRLBUS_CONST_IN_FLASH). NULL or size 0: the request is answered 0x8000 and the Core asks GET_BASE_CONF. */
    const uint8_t *binary_config;
    uint16_t binary_config_size; /* at most 65534 */
    /* Optional decoder counters (frame.h), counted into when not NULL. */
    ctrlbus_decoder_stats_t *decoder_stats;

    /* ---- behaviour ----------------------------------------------------------------------- */
    ctrlbus_base_profile_t profile;
    bool standard_answers;        /* false (default): OK and ERROR in long frames (reference) */
    bool reference_checksum_code; /* answer a checksum mismatch with the reference's 0x00C0 */
    uint16_t frame_timeout_ms;    /* 0: CTRLBUS_DEFAULT_TIMEOUT_MS (10); CTRLBUS_BASE_TIMEOUT_OFF */
    uint32_t watchdog_ms; /* 0: CTRLBUS_BASE_DEFAULT_WATCHDOG_MS (1000); CTRLBUS_BASE_WATCHDOG_OFF;
                           * below 2^31 */
    ctrlbus_base_limits_t limits;

    /* ---- output -------------------------------------------------------------------------- */
    ctrlbus_write_fn write; /* required: where answers go (called only from ctrlbus_base_poll()) */
    /* write's own argument, apart from `context`, so that a UART driver written once (its state
     * here) serves any application (its state in `context`). */
    void *write_context;

    /* ---- the application: handlers, called from ctrlbus_base_poll() with `context` ------- */
    /* One rule per callback below. "Mandatory": one of the 13 requests every base must answer
     * (docs/protocol.md §5); a Core gives up on a base that answers one 0x8000, and
     * ctrlbus_base_missing_handlers() names those left NULL. Every answer struct arrives zeroed,
     * so a field left alone reads 0. Which profile a Core needs: CTRLBUS_PROFILE_REFERENCE for a
     * SLAMWARE Core with the 2018/v4 firmware sizes, CTRLBUS_PROFILE_SDK2020 for a master on the
     * vendor's 2020 SDK (ctrlbus_base_profile_t); `ctrlbus check --profile` tells which passes. */
    void *context;
    /* Mandatory. CONNECT_BASE (version 1; the stack answers other versions 0x8000): model (ASCII),
     * firmware and hardware versions, serial. The profile decides whether the
     * firmware_version_suffix is sent (see ctrlbus_base_profile_t). */
    int32_t (*connect_info)(void *context, ctrlbus_connect_base_answer_t *out);
    /* Mandatory. GET_BASE_CONF: not a handler but the answer itself, read field by field while it
     * is written (264 bytes that never sit on the stack). The application owns it and may change
     * it between polls; NULL: not supported (0x8000). A struct its check refuses (a count over 8)
     * is answered 0x8002. With CTRLBUS_CONST_IN_FLASH (ctrlbus_config.h) it is read as program
     * memory: on AVR a PROGMEM constant, which then costs no RAM. sensor_num and bumper_num (0..8) say how many of the sensor_data
     * channels and bumper_data bits are real; positions and radius in mm Q8 (CTRLBUS_Q8()). */
    const ctrlbus_get_base_conf_answer_t *base_conf;
    /* Mandatory. GET_BASE_STATUS: battery percent, charging and docking state, error bits. */
    int32_t (*status)(void *context, ctrlbus_get_base_status_answer_t *out);
    /* Mandatory. GET_BASE_MOTOR_DATA: each wheel's total travel in mm since start-up (wraps). */
    int32_t (*motor_data)(void *context, ctrlbus_get_base_motor_data_answer_t *out);
    /* Mandatory. GET_BASE_SENSOR_DATA: channel i (mm Q16) is base_conf->sensors[i]; the channels
     * from sensor_num on must read 0 (leave them: they arrive zeroed). 0 also means "no echo". */
    int32_t (*sensor_data)(void *context, ctrlbus_get_base_sensor_data_answer_t *out);
    /* Mandatory. GET_BASE_BUMPER_DATA: bit i of bitmap is bumper i of base_conf (0..bumper_num-1),
     * then the cliff sensors, ACTIVE LOW (0 = triggered): set every bit you do not drive to 1
     * (0xFFFFFFFF: nothing pressed), since a zeroed bitmap reads "all pressed". payload_size 0
     * (as zeroed) means 4 bytes. */
    int32_t (*bumper_data)(void *context, ctrlbus_get_base_bumper_data_answer_t *out);
    /* Mandatory. GET_CHARGER_DATA, beacon data (data type 0; the stack answers other types
     * 0x8000): probe_count probes (3: left, main, right), each a bitmap of the dock beacons that
     * probe sees (bit0 left, bit1 main, bit2 right); left zeroed: no probe, no beacon seen.
     * out->probes must point at storage that outlives the call (the application's own array). */
    int32_t (*charger_data)(void *context, ctrlbus_get_charger_data_answer_t *out);
    /* Mandatory. SET_BASE_MOTOR: left and right wheel speeds in mm/s, after the limits. Also the
     * default way the motor watchdog stops the wheels (set_wheel_speeds(context, 0, 0)). */
    int32_t (*set_wheel_speeds)(void *context, int32_t left_mm_s, int32_t right_mm_s);
    /* Mandatory. SET_V_AND_GET_DEADRECKON: apply the velocity (after the limits) and fill in the
     * motion since the previous call (ctrlbus/diffdrive.h helps with both). has_timestamp_ms may
     * be left false: the profile decides whether the field is sent and fills it in. */
    int32_t (*set_velocity)(void *context,
                            const ctrlbus_set_v_and_get_deadreckon_request_t *velocity,
                            ctrlbus_set_v_and_get_deadreckon_answer_t *out);
    /* Optional. The motor watchdog expired: stop the wheels. NULL: set_wheel_speeds(context, 0, 0) (and
     * nothing if that is NULL too: a base that moves must provide one of them). */
    void (*stop_motors)(void *context);
    /* Optional. SEND_EVENT: any code, known or not. NULL: ignored (still answered OK). */
    int32_t (*on_event)(void *context, uint8_t event);
    /* Optional. BASE_CMD REBOOT: the stack answers OK, and once the answer's last byte has been handed to
     * write, forgets its session as a rebooted base would (the bytes received so far, the
     * pending commands (nCMD released), the health registry, the watchdog's state, the uptime
     * origin; the counters stay), then calls this. On an MCU it should wait until the UART has
     * sent the last byte, then reset; a host base may simply return and carry on.
     * NULL: REBOOT is answered 0x8000. */
    void (*reboot)(void *context);
    /* Optional. BASE_CMD ENTER_DFU: called like reboot, after the OK answer. NULL: answered 0x8000. */
    void (*enter_dfu)(void *context);
    /* Optional. The nCMD line (docs/protocol.md [link-ncmd]): called with true when a command becomes
     * pending (drive nCMD low), false when the queue runs empty (release it). NULL: no line. */
    void (*command_line)(void *context, bool asserted);
} ctrlbus_base_config_t;

/* The base stack instance. Caller-owned (usually static); treat the fields as private. */
typedef struct {
    const ctrlbus_base_config_t *config;
    /* The bytes first: a Cortex-M0 loads a byte at offsets 0..31 in one instruction. */
    uint8_t health_count;
    uint8_t command_head; /* with no command_queue storage: the pending command itself */
    uint8_t command_count;
    uint8_t flags;
    ctrlbus_decoder_t decoder;
    volatile uint16_t rx_head;     /* next byte to write; written by ctrlbus_base_feed() only */
    volatile uint16_t rx_tail;     /* next byte to read; written by ctrlbus_base_poll() only */
    volatile uint32_t rx_dropped;  /* bytes that found the ring full; written by feed only */
    uint32_t last_feed_ms;         /* the last CTRL_BUS frame (or start-up) */
    uint32_t boot_ms;              /* ctrlbus_base_init() or the last reboot: the uptime origin */
    uint32_t watchdog_trips;
    uint32_t clamped_commands;
} ctrlbus_base_t;

/* What the stack has counted since ctrlbus_base_init() (reboots keep them). */
typedef struct {
    /* The motor watchdog stopped wheels that were commanded to move (an idle expiry, with the
     * last command zero, is not a trip). */
    uint32_t watchdog_trips;
    /* Commands that the velocity limits changed. */
    uint32_t clamped_commands;
    /* Received bytes lost because the ring was full (the main loop polled too rarely). */
    uint32_t rx_dropped;
} ctrlbus_base_counters_t;

/* Starts the stack at time now_ms with config (kept by pointer: see ctrlbus_base_config_t). The
 * watchdog is armed from now (as base_ref v4). Call it before anything can call
 * ctrlbus_base_feed() (enable the UART interrupt afterwards).
 * Returns CTRLBUS_OK, or CTRLBUS_ERR_ARGUMENT for a NULL base or config, a missing write callback,
 * rx_ring or frame_buffer, an rx_ring_size below 2, a frame_buffer_size below 5, a
 * binary_config_size above 65534, or the sdk2020 profile with standard_answers;
 * CTRLBUS_ERR_UNSUPPORTED for a config that asks for a feature this build compiled out
 * (ctrlbus/ctrlbus_config.h): health_entries, command_queue, a velocity limit, the sdk2020
 * profile or a binary_config. A config without some of the mandatory handlers is accepted:
 * ctrlbus_base_missing_handlers() says which.
 * Not ISR-safe. Cost: O(1). */
int32_t ctrlbus_base_init(ctrlbus_base_t *base, const ctrlbus_base_config_t *config,
                          uint32_t now_ms);

/* The mandatory handlers (see ctrlbus_base_config_t) that a config leaves NULL, one bit each:
 * a base that answers them 0x8000 is refused by a Core, and otherwise that shows only at run
 * time. ctrlbus_base_init() accepts such a config (a base under construction may lack some);
 * call this after it, in a debug build or a start-up self-test. 0: none missing. */
#define CTRLBUS_BASE_NEEDS_CONNECT_INFO 0x001u
#define CTRLBUS_BASE_NEEDS_BASE_CONF 0x002u
#define CTRLBUS_BASE_NEEDS_STATUS 0x004u
#define CTRLBUS_BASE_NEEDS_MOTOR_DATA 0x008u
#define CTRLBUS_BASE_NEEDS_SENSOR_DATA 0x010u
#define CTRLBUS_BASE_NEEDS_BUMPER_DATA 0x020u
#define CTRLBUS_BASE_NEEDS_CHARGER_DATA 0x040u
#define CTRLBUS_BASE_NEEDS_SET_WHEEL_SPEEDS 0x080u
#define CTRLBUS_BASE_NEEDS_SET_VELOCITY 0x100u

/* Which mandatory handlers base's config lacks (CTRLBUS_BASE_NEEDS_* bits; 0 for a NULL base or
 * one not initialised). Inline, so that a firmware that never asks pays nothing for it.
 * ISR-safe. Cost: O(1). */
static inline uint16_t ctrlbus_base_missing_handlers(const ctrlbus_base_t *base)
{
    const ctrlbus_base_config_t *config = base != NULL ? base->config : NULL;
    unsigned missing = 0u;
    if (config != NULL) {
        missing |= config->connect_info == NULL ? CTRLBUS_BASE_NEEDS_CONNECT_INFO : 0u;
        missing |= config->base_conf == NULL ? CTRLBUS_BASE_NEEDS_BASE_CONF : 0u;
        missing |= config->status == NULL ? CTRLBUS_BASE_NEEDS_STATUS : 0u;
        missing |= config->motor_data == NULL ? CTRLBUS_BASE_NEEDS_MOTOR_DATA : 0u;
        missing |= config->sensor_data == NULL ? CTRLBUS_BASE_NEEDS_SENSOR_DATA : 0u;
        missing |= config->bumper_data == NULL ? CTRLBUS_BASE_NEEDS_BUMPER_DATA : 0u;
        missing |= config->charger_data == NULL ? CTRLBUS_BASE_NEEDS_CHARGER_DATA : 0u;
        missing |= config->set_wheel_speeds == NULL ? CTRLBUS_BASE_NEEDS_SET_WHEEL_SPEEDS : 0u;
        missing |= config->set_velocity == NULL ? CTRLBUS_BASE_NEEDS_SET_VELOCITY : 0u;
    }
    return (uint16_t)missing;
}

/* Puts received bytes into the ring for the next ctrlbus_base_poll(). Returns how many it took
 * (0..len): bytes that find the ring full are dropped and counted in rx_dropped (a caller that can
 * wait, such as a host thread, may offer the rest again later). Does nothing with a NULL base or
 * data (returns 0).
 * ISR-safe: once ctrlbus_base_init() has returned, it may interrupt any other function of this
 * header on the same instance, as long as only one context feeds a given instance (single
 * producer). Cost: O(len): ctrlbus_base_feed_byte() for each byte. */
size_t ctrlbus_base_feed(ctrlbus_base_t *base, const uint8_t *data, size_t len);

/* Puts one received byte into the ring: a UART receive interrupt's call. Returns true when it was
 * taken, false when the ring was full (the byte is dropped and counted in rx_dropped) or base is
 * NULL. The same contract as ctrlbus_base_feed() with len 1 (ISR-safe, single producer).
 * Cost: O(1), one fence. */
bool ctrlbus_base_feed_byte(ctrlbus_base_t *base, uint8_t byte);

/* How many bytes the ring can take now (0 for a NULL base): ctrlbus_base_feed() would take that
 * many. For a receive path that can leave bytes where they are (a UART's FIFO or holding register,
 * a DMA buffer, a host's socket): take a byte only while this is above 0, and pause the path
 * otherwise (mask the receive interrupt until the main loop has polled), so that a slow main loop
 * holds the sender back, or loses bytes in the UART, instead of dropping them here.
 * ISR-safe in the producer's context (single producer, as ctrlbus_base_feed()): the count can only
 * grow until the producer feeds again. Cost: O(1). */
size_t ctrlbus_base_rx_free(const ctrlbus_base_t *base);

/* The main loop's work, at time now_ms: runs the motor watchdog (stopping the wheels through
 * stop_motors or set_wheel_speeds when no CTRL_BUS frame came for more than watchdog_ms, once per
 * silence; a stop of moving wheels counts a trip and registers the health warning
 * CTRLBUS_HEALTH_WATCHDOG_TRIPPED), then takes every byte that was in the ring when it started,
 * decodes it, and answers each request and decoder event through config->write, in stream order;
 * then applies the inter-byte timeout at now_ms. Returns nothing: what it does shows on the wire,
 * in the handlers' calls and in ctrlbus_base_counters(). A write callback that fails cuts that
 * answer short; the stack carries on with the next.
 * Not ISR-safe (main loop only). Cost: the decoder's cost for the bytes taken (O(1) per byte on a
 * clean link; frame.h gives the worst case: the ring's bytes go through ctrlbus_decoder_feed() one
 * contiguous run at a time, and their slots are released after the answers they complete),
 * plus for each request one look-up in the request table (17 rows), its handler, and the
 * answer's size in byte visits (one write call per run of integer fields, per text byte, and for
 * the header and the checksum); no work beyond the ring's content at entry. Stack: see
 * "Footprint" above. */
void ctrlbus_base_poll(ctrlbus_base_t *base, uint32_t now_ms);

/* A new line: the host connected a new peer (a new TCP connection, a re-plugged cable), so the
 * bytes received so far and any half-received frame belong to a link that is gone. Forgets them
 * (the ring's unread bytes and the decoder's buffer); everything else (watchdog, queue, health,
 * counters) is kept. Call it before feeding the new peer's first byte.
 * Not ISR-safe: main loop only, with the feeding interrupt masked if there is one. Cost: O(1). */
void ctrlbus_base_reset_line(ctrlbus_base_t *base);

/* Registers a health error the Core reads with HEALTH_MGMT (docs/protocol.md §10): code is the
 * u32 layout of CTRLBUS_HEALTH_CODE(), message at most 31 ASCII characters (NULL: empty), kept by
 * pointer (a string constant is right). Entries keep registration order (GET_ERROR's index).
 * Returns 1 when added, 0 when the code was registered already (nothing changes then),
 * CTRLBUS_ERR_ARGUMENT for a NULL base or a bad message, CTRLBUS_ERR_TOO_BIG when the registry is
 * full (or has no storage and code is not the watchdog's), CTRLBUS_ERR_UNSUPPORTED when the
 * registry is compiled out (CTRLBUS_CONFIG_HEALTH 0). Not ISR-safe (main loop or handlers).
 * Cost: O(health_capacity) plus O(message length). */
int32_t ctrlbus_base_health_add(ctrlbus_base_t *base, uint32_t code, const char *message);

/* Removes the health error with this code, as the Core's HEALTH_CLR_ERROR does. A condition that
 * still holds may simply be registered again. Returns 1 when removed, 0 when it was not there,
 * CTRLBUS_ERR_ARGUMENT for a NULL base, CTRLBUS_ERR_UNSUPPORTED without the registry
 * (CTRLBUS_CONFIG_HEALTH 0). Not ISR-safe. Cost: O(health_capacity). */
int32_t ctrlbus_base_health_clear(ctrlbus_base_t *base, uint32_t code);

/* How many health errors are registered (GET_HEALTH's error_count); 0 for a NULL base.
 * Not ISR-safe (it reads what the main loop writes). Cost: O(1). */
uint8_t ctrlbus_base_health_count(const ctrlbus_base_t *base);

/* Offers an external command to the Core (docs/protocol.md §5.12): POLL_BASE_CMD answers the
 * oldest queued command until POLL_BASE_ANS_CMD takes it; the command_line callback reports
 * whether one is pending. code must be one of the protocol's external commands (0x51-0x53,
 * 0x80-0x82, 0x90, 0xA0-0xA4, 0xAF, 0xB0): the Core only supports those.
 * Returns CTRLBUS_OK, CTRLBUS_ERR_ARGUMENT for an unknown code or a NULL base, CTRLBUS_ERR_TOO_BIG
 * when the queue is full, CTRLBUS_ERR_UNSUPPORTED without external commands
 * (CTRLBUS_CONFIG_COMMAND_QUEUE 0). Not ISR-safe (main loop or handlers). Cost: O(1). */
int32_t ctrlbus_base_queue_command(ctrlbus_base_t *base, uint8_t code);

/* Drops every queued external command (and releases nCMD). Not ISR-safe. Cost: O(1). */
void ctrlbus_base_clear_commands(ctrlbus_base_t *base);

/* How many external commands are queued; 0 for a NULL base. Not ISR-safe. Cost: O(1). */
uint8_t ctrlbus_base_commands_pending(const ctrlbus_base_t *base);

/* Copies the counters into *out (zeros for a NULL base). ISR-safe to call, though a counter may
 * be one behind if the main loop is updating it. Cost: O(1). */
void ctrlbus_base_counters(const ctrlbus_base_t *base, ctrlbus_base_counters_t *out);

#ifdef __cplusplus
}
#endif

#endif
