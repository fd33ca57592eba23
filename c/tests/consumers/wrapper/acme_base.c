/* SPDX-License-Identifier: MIT */
#include "acme_base.h"

#include "ctrlbus/ctrlbus.h"

int32_t acme_base_radius_mm_q8(void)
{
    return CTRLBUS_Q8(170);
}
