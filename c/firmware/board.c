/* Board support for mps2-an385: SysTick millisecond clock and the CMSDK UART0 driver. */
#include "board.h"

#include "mps2_an385.h"
#include "vectors.h"

/* Firmware-wide state shared with the interrupt handlers; the library itself has none. */
static volatile uint32_t elapsed_ms;
static board_rx_handler_t uart_rx_handler;
static void *uart_rx_context;

#define UART_BAUD 115200u

void board_init(board_rx_handler_t rx_handler, void *context)
{
    uart_rx_handler = rx_handler;
    uart_rx_context = context;

    SYST_RVR = MPS2_SYSCLK_HZ / 1000u - 1u;
    SYST_CVR = 0;
    SYST_CSR = SYST_CSR_CLKSOURCE_CPU | SYST_CSR_TICKINT | SYST_CSR_ENABLE;

    CMSDK_UART_BAUDDIV(MPS2_UART0_BASE) = MPS2_SYSCLK_HZ / UART_BAUD;
    CMSDK_UART_CTRL(MPS2_UART0_BASE) = CMSDK_UART_CTRL_TX_EN | CMSDK_UART_CTRL_RX_EN | CMSDK_UART_CTRL_RX_IRQ_EN;
    NVIC_ICPR0 = 1u << MPS2_UART0_RX_IRQN;
    NVIC_ISER0 = 1u << MPS2_UART0_RX_IRQN;
}

uint32_t board_now_ms(void)
{
    return elapsed_ms;
}

void systick_handler(void)
{
    elapsed_ms = elapsed_ms + 1u;
}

void uart0_rx_handler(void)
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
    __asm__ volatile("wfi" ::: "memory");
}

void board_reset(void)
{
    __asm__ volatile("dsb" ::: "memory");
    SCB_AIRCR = SCB_AIRCR_VECTKEY | SCB_AIRCR_SYSRESETREQ;
    __asm__ volatile("dsb" ::: "memory");
    for (;;) {
    }
}
