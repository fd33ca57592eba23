/* SPDX-License-Identifier: MIT */
/* Board support for mps2-an385: SysTick millisecond clock and the CMSDK UART0 driver. */
#include "board.h"

#include "cortex_m.h"
#include "mps2_an385.h"

/* Firmware-wide state shared with the interrupt handlers; the library itself has none. */
static board_rx_handler_t uart_rx_handler;
static void *uart_rx_context;

/* The millisecond clock: APB timer 0 counts down at the system clock, free-running; the main loop
 * turns the cycles since its last read into milliseconds. Counting SysTick interrupts instead
 * loses time under QEMU (about a fifth of the ticks on this machine: ticks that fall due while
 * the emulated CPU is not running merge into one interrupt), and a counter read does not. */
static uint32_t clock_last_value;
static uint32_t clock_cycles; /* cycles not yet counted as a whole millisecond */
static uint32_t clock_ms;
#define CYCLES_PER_MS (MPS2_SYSCLK_HZ / 1000u)

#define UART_BAUD 115200u

/* The shared vector table (../ports/cortex_m/startup.c) is sized and wired by the Makefile's
 * PORT_IRQ_COUNT and PORT_UART_IRQN: they must be this board's. */
typedef char irq_count_is_the_boards[PORT_IRQ_COUNT == MPS2_IRQ_COUNT ? 1 : -1];
typedef char uart_irq_is_uart0_rx[PORT_UART_IRQN == MPS2_UART0_RX_IRQN ? 1 : -1];

void board_init(board_rx_handler_t rx_handler, void *context)
{
    uart_rx_handler = rx_handler;
    uart_rx_context = context;

    CMSDK_TIMER_RELOAD(MPS2_TIMER0_BASE) = 0xFFFFFFFFu;
    CMSDK_TIMER_VALUE(MPS2_TIMER0_BASE) = 0xFFFFFFFFu;
    CMSDK_TIMER_CTRL(MPS2_TIMER0_BASE) = CMSDK_TIMER_CTRL_ENABLE;
    clock_last_value = 0xFFFFFFFFu;

    cortex_m_start_tick(CYCLES_PER_MS);

    CMSDK_UART_BAUDDIV(MPS2_UART0_BASE) = MPS2_SYSCLK_HZ / UART_BAUD;
    CMSDK_UART_CTRL(MPS2_UART0_BASE) = CMSDK_UART_CTRL_TX_EN | CMSDK_UART_CTRL_RX_EN | CMSDK_UART_CTRL_RX_IRQ_EN;
    cortex_m_enable_irq(MPS2_UART0_RX_IRQN);
}

uint32_t board_now_ms(void)
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
    /* Nothing to do: the tick only wakes the main loop from board_wait_for_interrupt(). */
}

void port_uart_irq_handler(void)
{
    /* Clear the interrupt before draining, so a byte that lands after the last read raises it
     * again instead of being left unnoticed in the holding register. */
    CMSDK_UART_INTSTATUS(MPS2_UART0_BASE) = CMSDK_UART_INT_RX;
    while (CMSDK_UART_STATE(MPS2_UART0_BASE) & CMSDK_UART_STATE_RX_FULL) {
        uint8_t byte = (uint8_t)CMSDK_UART_DATA(MPS2_UART0_BASE);
        if (uart_rx_handler != 0) {
            uart_rx_handler(uart_rx_context, byte);
        }
    }
}

void board_uart_write(const uint8_t *data, size_t size)
{
    for (size_t i = 0; i < size; i++) {
        while (CMSDK_UART_STATE(MPS2_UART0_BASE) & CMSDK_UART_STATE_TX_FULL) {
        }
        CMSDK_UART_DATA(MPS2_UART0_BASE) = data[i];
    }
}

void board_wait_for_interrupt(void)
{
    cortex_m_wait_for_interrupt();
}

void board_reset(void)
{
    __asm__ volatile("dsb" ::: "memory");
    SCB_AIRCR = SCB_AIRCR_VECTKEY | SCB_AIRCR_SYSRESETREQ;
    __asm__ volatile("dsb" ::: "memory");
    for (;;) {
    }
}
