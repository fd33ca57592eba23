/* SPDX-License-Identifier: MIT */
/* What every Cortex-M port shares: the core's own registers (SysTick, NVIC, SCB), the handlers the
 * vector table (startup.c) points to, and the wait-for-interrupt instruction. */
#ifndef CTRLBUS_PORT_CORTEX_M_H
#define CTRLBUS_PORT_CORTEX_M_H

#include <stdint.h>

#define CORTEX_M_REG(address) (*(volatile uint32_t *)(uintptr_t)(address))

#define SYST_CSR CORTEX_M_REG(0xE000E010u)
#define SYST_RVR CORTEX_M_REG(0xE000E014u)
#define SYST_CVR CORTEX_M_REG(0xE000E018u)
#define SYST_CSR_ENABLE 0x1u
#define SYST_CSR_TICKINT 0x2u
#define SYST_CSR_CLKSOURCE_CPU 0x4u

/* NVIC set-enable / clear-enable / clear-pending for interrupt n (0..31 in the first word, and so
 * on). */
#define NVIC_ISER(n) CORTEX_M_REG(0xE000E100u + 4u * ((n) / 32u))
#define NVIC_ICER(n) CORTEX_M_REG(0xE000E180u + 4u * ((n) / 32u))
#define NVIC_ICPR(n) CORTEX_M_REG(0xE000E280u + 4u * ((n) / 32u))
#define NVIC_BIT(n) (1u << ((n) % 32u))

/* The board's handlers: the UART interrupt (PORT_UART_IRQN, a -D of the board's build) and the
 * SysTick tick that wakes the main loop. */
void port_uart_irq_handler(void);
void port_systick_handler(void);

/* Enables interrupt n in the NVIC, with any stale pending state cleared first. */
static inline void cortex_m_enable_irq(uint32_t n)
{
    NVIC_ICPR(n) = NVIC_BIT(n);
    NVIC_ISER(n) = NVIC_BIT(n);
}

/* Masks interrupt n in the NVIC (it can still become pending) until cortex_m_unmask_irq(). The
 * barriers make sure the handler no longer runs once this returns. */
static inline void cortex_m_mask_irq(uint32_t n)
{
    NVIC_ICER(n) = NVIC_BIT(n);
    __asm__ volatile("dsb\n\tisb" ::: "memory");
}

/* Unmasks interrupt n, keeping its pending state: what became pending meanwhile runs now. */
static inline void cortex_m_unmask_irq(uint32_t n)
{
    NVIC_ISER(n) = NVIC_BIT(n);
}

/* Starts SysTick interrupting every `cycles` core clocks (at most 2^24). */
static inline void cortex_m_start_tick(uint32_t cycles)
{
    SYST_RVR = cycles - 1u;
    SYST_CVR = 0;
    SYST_CSR = SYST_CSR_CLKSOURCE_CPU | SYST_CSR_TICKINT | SYST_CSR_ENABLE;
}

static inline void cortex_m_wait_for_interrupt(void)
{
    __asm__ volatile("wfi" ::: "memory");
}

#endif
