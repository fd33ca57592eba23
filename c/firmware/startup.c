/* SPDX-License-Identifier: MIT */
/* Cortex-M3 start-up for mps2-an385: the vector table and the reset handler.
 *
 * The reset handler copies initialised data from its load address (after the code) to RAM,
 * zeroes .bss and calls main. Anything unexpected (a fault, an interrupt nobody enabled) parks
 * the core in fault_handler, where a debugger finds it. */
#include <stdint.h>

#include "mps2_an385.h"
#include "vectors.h"

int main(void);

/* Symbols from the linker script (mps2_an385.ld). */
extern uint32_t __data_load[];
extern uint32_t __data_start[];
extern uint32_t __data_end[];
extern uint32_t __bss_start[];
extern uint32_t __bss_end[];
extern uint32_t __stack_top[];

typedef void (*vector_t)(void);

static void fault_handler(void)
{
    for (;;) {
    }
}

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

/* 16 system exceptions, then the board's 32 interrupt lines. */
#define SYSTEM_VECTORS 16u
#define UART0_RX_VECTOR (SYSTEM_VECTORS + MPS2_UART0_RX_IRQN)

__attribute__((section(".vectors"), used)) static const vector_t vector_table[SYSTEM_VECTORS + MPS2_IRQ_COUNT] = {
    [0] = (vector_t)(uintptr_t)__stack_top,
    [1] = reset_handler,
    [2] = fault_handler,  /* NMI */
    [3] = fault_handler,  /* HardFault */
    [4] = fault_handler,  /* MemManage */
    [5] = fault_handler,  /* BusFault */
    [6] = fault_handler,  /* UsageFault */
    [11] = fault_handler, /* SVCall */
    [12] = fault_handler, /* DebugMonitor */
    [14] = fault_handler, /* PendSV */
    [15] = systick_handler,
    [UART0_RX_VECTOR] = uart0_rx_handler,
};
