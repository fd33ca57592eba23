/* SPDX-License-Identifier: MIT */
/* Exception and interrupt handlers that the vector table (startup.c) points to. */
#ifndef CTRLBUS_FW_VECTORS_H
#define CTRLBUS_FW_VECTORS_H

void reset_handler(void);
void systick_handler(void);
void uart0_rx_handler(void);

#endif
