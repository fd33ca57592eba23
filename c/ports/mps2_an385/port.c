/* SPDX-License-Identifier: MIT */
/* c/ports/port.h for QEMU's mps2-an385 board (ARM AN385: Cortex-M3 on the MPS2 FPGA, 25 MHz), as
 * `qemu-system-arm -M mps2-an385` models it (hw/arm/mps2.c; UART0 is QEMU's serial 0). QEMU-only:
 * the board is an FPGA image, so this port has no chip image (README.md).
 *
 * UART: CMSDK APB UART0 at 0x40004000, 115200 8N1; its RX interrupt (IRQ 0) hands each byte to
 * port_uart_received() while port_uart_room() allows (port.h). QEMU's UART holds one received
 * byte and takes the next from the host only once the firmware has read it, so the host is held
 * back rather than bytes lost.
 * Clock: CMSDK APB timer 0 counts down at the system clock, free-running, and port_millis() turns
 * the cycles since its last call into milliseconds (counting SysTick interrupts instead loses time
 * under QEMU: ticks that fall due while the emulated CPU is not running merge into one interrupt;
 * a counter read does not). It must be called at least every 171 s (the counter's wrap). SysTick
 * interrupts every millisecond, only to wake the main loop from WFI.
 * Reset: port_reset() (PORT_HAS_RESET) through the Cortex-M3's AIRCR, for BASE_CMD REBOOT. */
#include <stdbool.h>

#include "cortex_m.h"
#include "mps2_an385.h"
#include "port.h"

/* The port's state, shared with the interrupt handlers; the library itself has none. */
static uint32_t clock_last_value;
static uint32_t clock_cycles; /* cycles not yet counted as a whole millisecond */
static uint32_t clock_ms;
static volatile uint8_t rx_paused; /* the receive interrupt is masked: the application was full */
#define CYCLES_PER_MS (MPS2_SYSCLK_HZ / 1000u)

#define UART_BAUD 115200u

/* The shared vector table (cortex_m/startup.c) is sized and wired by the Makefile's
 * PORT_IRQ_COUNT and PORT_UART_IRQN: they must be this board's. */
typedef char irq_count_is_the_boards[PORT_IRQ_COUNT == MPS2_IRQ_COUNT ? 1 : -1];
typedef char uart_irq_is_uart0_rx[PORT_UART_IRQN == MPS2_UART0_RX_IRQN ? 1 : -1];

void port_init(void)
{
    CMSDK_TIMER_RELOAD(MPS2_TIMER0_BASE) = 0xFFFFFFFFu;
    CMSDK_TIMER_VALUE(MPS2_TIMER0_BASE) = 0xFFFFFFFFu;
    CMSDK_TIMER_CTRL(MPS2_TIMER0_BASE) = CMSDK_TIMER_CTRL_ENABLE;
    clock_last_value = 0xFFFFFFFFu;

    cortex_m_start_tick(CYCLES_PER_MS);

    CMSDK_UART_BAUDDIV(MPS2_UART0_BASE) = MPS2_SYSCLK_HZ / UART_BAUD;
    CMSDK_UART_CTRL(MPS2_UART0_BASE) = CMSDK_UART_CTRL_TX_EN | CMSDK_UART_CTRL_RX_EN | CMSDK_UART_CTRL_RX_IRQ_EN;
    cortex_m_enable_irq(MPS2_UART0_RX_IRQN);
}

uint32_t port_millis(void)
{
    uint32_t value = CMSDK_TIMER_VALUE(MPS2_TIMER0_BASE);
    uint32_t elapsed = clock_last_value - value; /* a down-counter; wraps every 171.8 s */
    clock_last_value = value;
    clock_ms += elapsed / CYCLES_PER_MS;
    clock_cycles += elapsed % CYCLES_PER_MS;
    if (clock_cycles >= CYCLES_PER_MS) {
        clock_cycles -= CYCLES_PER_MS;
        clock_ms++;
    }
    return clock_ms;
}

void port_systick_handler(void)
{
    /* Nothing to do: the tick only wakes the main loop from port_idle(). */
}

/* Hands the UART's waiting bytes to the application while it has room. Returns false when one had
 * to stay in the holding register. Only one context runs it at a time: the interrupt, or
 * port_idle() while the interrupt is masked. */
static bool take_received(void)
{
    while (CMSDK_UART_STATE(MPS2_UART0_BASE) & CMSDK_UART_STATE_RX_FULL) {
        if (port_uart_room() == 0u) {
            return false;
        }
        port_uart_received((uint8_t)CMSDK_UART_DATA(MPS2_UART0_BASE));
    }
    return true;
}

void port_uart_irq_handler(void)
{
    /* Clear the interrupt before draining, so a byte that lands after the last read raises it
     * again instead of being left unnoticed in the holding register. A byte left there because
     * the application is full raises nothing more: port_idle() takes it itself. */
    CMSDK_UART_INTSTATUS(MPS2_UART0_BASE) = CMSDK_UART_INT_RX;
    if (!take_received()) {
        cortex_m_mask_irq(PORT_UART_IRQN); /* until port_idle(), after the main loop has polled */
        rx_paused = 1u;
    }
}

void port_uart_write(const uint8_t *data, size_t size)
{
    for (size_t i = 0; i < size; i++) {
        while (CMSDK_UART_STATE(MPS2_UART0_BASE) & CMSDK_UART_STATE_TX_FULL) {
        }
        CMSDK_UART_DATA(MPS2_UART0_BASE) = data[i];
    }
}

void port_idle(void)
{
    if (rx_paused && take_received()) { /* the interrupt is masked: nothing else takes bytes */
        rx_paused = 0u;
        cortex_m_unmask_irq(PORT_UART_IRQN); /* a byte that came after the last look runs it now */
    }
    cortex_m_wait_for_interrupt();
}

void port_reset(void)
{
    __asm__ volatile("dsb" ::: "memory");
    SCB_AIRCR = SCB_AIRCR_VECTKEY | SCB_AIRCR_SYSRESETREQ;
    __asm__ volatile("dsb" ::: "memory");
    for (;;) {
    }
}
