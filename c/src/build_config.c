/* SPDX-License-Identifier: MIT */
/* The library's effective build-time switches as a link-time symbol (ctrlbus/ctrlbus_config.h,
 * CTRLBUS_CONFIG_CHECK()). */
#include "ctrlbus/ctrlbus.h"

int32_t CTRLBUS_CONFIG_SYMBOL(void)
{
    return CTRLBUS_OK;
}
