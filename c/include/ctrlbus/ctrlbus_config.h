/* SPDX-License-Identifier: MIT */
/* ctrlbus build-time configuration: every feature switch of the library, in one place.
 *
 * How to set them (littlefs / nanopb style): define CTRLBUS_CONFIG_HEADER to a header of your own,
 * for example -DCTRLBUS_CONFIG_HEADER='"my_ctrlbus_config.h"' (CMake: -DCTRLBUS_CONFIG_HEADER=
 * /path/to/my_ctrlbus_config.h), and define the switches you change there; or define single
 * switches with -D. Whatever is not defined gets the default below. Every translation unit that
 * includes a ctrlbus header must see the same values (the CMake target exports the definition).
 *
 * Every switch is 1 (on) by default: the default build is the full library. Turning a switch off
 * removes code, never changes what a kept feature does on the wire. A feature that is compiled
 * out behaves clearly:
 *   - an optional request it served is answered ERROR 0x8000 (unsupported);
 *   - a mandatory request it served is still answered, as by a base that has nothing to report
 *     (see each switch);
 *   - the API functions that only it needs return CTRLBUS_ERR_UNSUPPORTED, and
 *     ctrlbus_base_init() refuses (CTRLBUS_ERR_UNSUPPORTED) a config that asks for it.
 *
 * What each switch saves is measured, not stated here: `make size` prints the base stack per target
 * in the default configuration, in the minimal one (every switch off) and with each switch off
 * alone, and docs/performance.md tables the figures.
 */
#ifndef CTRLBUS_CTRLBUS_CONFIG_H
#define CTRLBUS_CTRLBUS_CONFIG_H

#ifdef CTRLBUS_CONFIG_HEADER
#include CTRLBUS_CONFIG_HEADER
#endif

/* The health registry (ctrlbus_base_health_add/_clear, HEALTH_MGMT with registered errors, the
 * watchdog's health warning). Off: HEALTH_GET_HEALTH (mandatory) answers no errors,
 * HEALTH_GET_ERROR and HEALTH_CLR_ERROR answer 0x8002 (no such error, as with an empty registry),
 * ctrlbus_base_health_add/_clear return CTRLBUS_ERR_UNSUPPORTED, and a config with
 * health_entries is refused. */
#ifndef CTRLBUS_CONFIG_HEALTH
#define CTRLBUS_CONFIG_HEALTH 1
#endif

/* External commands offered to the Core (ctrlbus_base_queue_command, POLL_BASE_CMD with a
 * pending command, the nCMD line callback). Off: POLL_BASE_CMD (mandatory) always answers
 * "nothing pending", POLL_BASE_ANS_CMD answers OK, ctrlbus_base_queue_command returns
 * CTRLBUS_ERR_UNSUPPORTED, and a config with command_queue storage is refused. */
#ifndef CTRLBUS_CONFIG_COMMAND_QUEUE
#define CTRLBUS_CONFIG_COMMAND_QUEUE 1
#endif

/* The velocity limits (ctrlbus_base_config_t.limits, docs/protocol.md §9.2), including the
 * differential-drive arithmetic they need. Off: commands reach the handlers unchanged, and a
 * config with any limit set is refused. (ctrlbus/diffdrive.h's wheel speeds and scaling are in
 * 32-bit arithmetic: no libgcc multiply or divide.) */
#ifndef CTRLBUS_CONFIG_LIMITS
#define CTRLBUS_CONFIG_LIMITS 1
#endif

/* The sdk2020 profile (CTRLBUS_PROFILE_SDK2020: CONNECT with its suffix, deadreckon with the
 * timestamp, bumpers padded to 4 bytes, POLL_BASE_CMD's FF 00). Off: only the reference profile;
 * a config asking for sdk2020 is refused. */
#ifndef CTRLBUS_CONFIG_PROFILE_SDK2020
#define CTRLBUS_CONFIG_PROFILE_SDK2020 1
#endif

/* GET_BASE_CONF_ADV (0x21), streamed from ctrlbus_base_config_t.binary_config. Off: the request
 * is answered 0x8000 (the Core then asks GET_BASE_CONF), and a config with a binary_config is
 * refused. */
#ifndef CTRLBUS_CONFIG_CONF_ADV
#define CTRLBUS_CONFIG_CONF_ADV 1
#endif

/* The master-side codecs of messages.h: request encoders (ctrlbus_request_write/_encode/
 * _payload_size/_cmd) and answer decoders (ctrlbus_answer_decode, ctrlbus_*_answer_decode), what
 * a Core or a test tool needs and a base never does. They live in their own file
 * (src/messages_master.c), so a base firmware linked with --gc-sections never pays for them;
 * off, they are neither compiled nor declared (using one is a compile error).
 * A base stack never links them; the switch only shortens the library's own build. */
#ifndef CTRLBUS_CONFIG_MASTER_CODECS
#define CTRLBUS_CONFIG_MASTER_CODECS 1
#endif

/* Where the application's constant answers live: the GET_BASE_CONF answer (config->base_conf,
 * 264 bytes on the wire) and the 0x21 blob (config->binary_config). 0 (default): ordinary memory.
 * 1: program memory that takes its own read instruction, such as an AVR's flash (PROGMEM): the
 * stack then reads them only through CTRLBUS_READ_CONST(dst, src, size), which is memcpy_P on AVR
 * (avr-libc) and memcpy elsewhere; define it when compiling the library for another such part.
 * On an ATmega328P this keeps the GET_BASE_CONF answer out of the 2 KB of RAM (c/ports/README.md:
 * the Uno's minimal base builds so). Only on a little-endian CPU (refused at compile time
 * otherwise). Not a feature switch: it changes no behaviour, and Zephyr, whose targets read const
 * data in place, has no option for it. It adds the answer's writer for that memory, and moves
 * the answer's 264 bytes from RAM to flash. */
#ifndef CTRLBUS_CONST_IN_FLASH
#define CTRLBUS_CONST_IN_FLASH 0
#endif

/* The profile a config whose `profile` is left zero gets (ctrlbus_base_profile_t, base.h). Define
 * it for the whole build, e.g. -DCTRLBUS_DEFAULT_PROFILE=CTRLBUS_PROFILE_SDK2020, to build a
 * firmware for the vendor's 2020 master SDK without touching its code (c/ports builds mps2-an385's
 * sdk2020 image so). Zero is CTRLBUS_PROFILE_REFERENCE, so with the sdk2020 default the reference
 * profile cannot be chosen at run time. */
#ifndef CTRLBUS_DEFAULT_PROFILE
#define CTRLBUS_DEFAULT_PROFILE CTRLBUS_PROFILE_REFERENCE
#endif

/* The effective switches, checked at link time. The library defines one function whose name spells
 * the switches it was compiled with, e.g. ctrlbus_config_h1_q1_l1_p1_a1_m1_f0 (health, command
 * queue, limits, sdk2020, conf_adv, master codecs, const in flash: 0 or 1), and
 * CTRLBUS_CONFIG_CHECK(), a statement for the firmware's start-up code, calls the one this
 * translation unit's switches name. When the library archive was built with other switches (a
 * config header not applied, a -D missing in one build), the link fails with "undefined reference
 * to ctrlbus_config_...", naming the switches the firmware expected. Cost: a call to a function
 * that returns 0 (a few bytes); nothing at all when not used (its own section). */
#if CTRLBUS_CONFIG_HEALTH
#define CTRLBUS_CONFIG_BIT_H_ 1
#else
#define CTRLBUS_CONFIG_BIT_H_ 0
#endif
#if CTRLBUS_CONFIG_COMMAND_QUEUE
#define CTRLBUS_CONFIG_BIT_Q_ 1
#else
#define CTRLBUS_CONFIG_BIT_Q_ 0
#endif
#if CTRLBUS_CONFIG_LIMITS
#define CTRLBUS_CONFIG_BIT_L_ 1
#else
#define CTRLBUS_CONFIG_BIT_L_ 0
#endif
#if CTRLBUS_CONFIG_PROFILE_SDK2020
#define CTRLBUS_CONFIG_BIT_P_ 1
#else
#define CTRLBUS_CONFIG_BIT_P_ 0
#endif
#if CTRLBUS_CONFIG_CONF_ADV
#define CTRLBUS_CONFIG_BIT_A_ 1
#else
#define CTRLBUS_CONFIG_BIT_A_ 0
#endif
#if CTRLBUS_CONFIG_MASTER_CODECS
#define CTRLBUS_CONFIG_BIT_M_ 1
#else
#define CTRLBUS_CONFIG_BIT_M_ 0
#endif
#if CTRLBUS_CONST_IN_FLASH
#define CTRLBUS_CONFIG_BIT_F_ 1
#else
#define CTRLBUS_CONFIG_BIT_F_ 0
#endif
#define CTRLBUS_CONFIG_NAME_(h, q, l, p, a, m, f)                                                  \
    ctrlbus_config_h##h##_q##q##_l##l##_p##p##_a##a##_m##m##_f##f
#define CTRLBUS_CONFIG_NAME(h, q, l, p, a, m, f) CTRLBUS_CONFIG_NAME_(h, q, l, p, a, m, f)
/* The name of the function for this translation unit's switches. */
#define CTRLBUS_CONFIG_SYMBOL                                                                      \
    CTRLBUS_CONFIG_NAME(CTRLBUS_CONFIG_BIT_H_, CTRLBUS_CONFIG_BIT_Q_, CTRLBUS_CONFIG_BIT_L_,       \
                        CTRLBUS_CONFIG_BIT_P_, CTRLBUS_CONFIG_BIT_A_, CTRLBUS_CONFIG_BIT_M_,       \
                        CTRLBUS_CONFIG_BIT_F_)
/* Links only against a library built with the same switches (see above). Main loop, once. */
#define CTRLBUS_CONFIG_CHECK() ((void)CTRLBUS_CONFIG_SYMBOL())

#endif
