/* SPDX-License-Identifier: MIT */
/* Cortex-M start-up shared by the Cortex-M ports: the vector table and the reset handler, which
 * copies .data from flash, zeroes .bss and calls main. The board's build defines PORT_IRQ_COUNT
 * (its number of interrupt lines) and PORT_UART_IRQN (its UART's). Anything unexpected (a fault,
 * an interrupt nobody enabled) parks the core in fault_handler, where a debugger finds it. */
#include <stdint.h>

#include "cortex_m.h"

int main(void);

/* Symbols of sections.ld. */
extern uint32_t __data_load[], __data_start[], __data_end[], __bss_start[], __bss_end[];
extern uint32_t __stack_top[];

typedef void (*vector_t)(void);

static void fault_handler(void)
{
    for (;;) {
    }
}

void reset_handler(void);
void reset_handler(void)
{
    const uint32_t *from = __data_load;
    for (uint32_t *to = __data_start; to < __data_end;) {
        *to++ = *from++;
    }
    for (uint32_t *to = __bss_start; to < __bss_end;) {
        *to++ = 0;
    }
    (void)main();
    for (;;) {
    }
}

#define SYSTEM_VECTORS 16u

__attribute__((section(".vectors"), used)) static const vector_t vector_table[SYSTEM_VECTORS + PORT_IRQ_COUNT] = {
    [0] = (vector_t)(uintptr_t)__stack_top,
    [1] = reset_handler,
    [2] = fault_handler, /* NMI */
    [3] = fault_handler, /* HardFault (MemManage, BusFault, UsageFault escalate to it when off) */
    [11] = fault_handler, /* SVCall */
    [14] = fault_handler, /* PendSV */
    [15] = port_systick_handler,
    [SYSTEM_VECTORS + PORT_UART_IRQN] = port_uart_irq_handler,
};
