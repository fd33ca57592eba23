/* SPDX-License-Identifier: MIT */
/* Every feature switch of ctrlbus/ctrlbus_config.h off: the smallest base stack. The C tests run
 * against it too (`make c-test-config-off`, part of `make test`): what is left must work, and
 * what is compiled out must answer and fail clearly. Each switch is guarded so that the tests,
 * which play the Core, can still build the master-side codecs for themselves
 * (-DCTRLBUS_CONFIG_MASTER_CODECS=1 on the test targets only). */
#ifndef CTRLBUS_CONFIG_HEALTH
#define CTRLBUS_CONFIG_HEALTH 0
#endif
#ifndef CTRLBUS_CONFIG_COMMAND_QUEUE
#define CTRLBUS_CONFIG_COMMAND_QUEUE 0
#endif
#ifndef CTRLBUS_CONFIG_LIMITS
#define CTRLBUS_CONFIG_LIMITS 0
#endif
#ifndef CTRLBUS_CONFIG_PROFILE_SDK2020
#define CTRLBUS_CONFIG_PROFILE_SDK2020 0
#endif
#ifndef CTRLBUS_CONFIG_CONF_ADV
#define CTRLBUS_CONFIG_CONF_ADV 0
#endif
#ifndef CTRLBUS_CONFIG_MASTER_CODECS
#define CTRLBUS_CONFIG_MASTER_CODECS 0
#endif
