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

/* The profile a config whose `profile` is left zero gets (ctrlbus_base_profile_t, base.h). Define
 * it for the whole build, e.g. -DCTRLBUS_DEFAULT_PROFILE=CTRLBUS_PROFILE_SDK2020, to build a
 * firmware for the vendor's 2020 master SDK without touching its code (c/firmware builds its
 * sdk2020 image so). Zero is CTRLBUS_PROFILE_REFERENCE, so with the sdk2020 default the reference
 * profile cannot be chosen at run time. */
#ifndef CTRLBUS_DEFAULT_PROFILE
#define CTRLBUS_DEFAULT_PROFILE CTRLBUS_PROFILE_REFERENCE
#endif

#endif
