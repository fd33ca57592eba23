/* SPDX-License-Identifier: MIT */
/* c/ports/port.h for the BBC micro:bit (nRF51822, Cortex-M0, 16 MHz, 16 KiB RAM), as
 * `qemu-system-arm -M microbit` models it (UART0 is QEMU's serial 0).
 *
 * UART: UART0 at 0x40002000, 115200 8N1; the RXDRDY interrupt (IRQ 2) hands each byte to
 * port_uart_received() while port_uart_room() allows (port.h). The pins are the micro:bit's USB
 * bridge: TX P0.24, RX P0.25.
 * Clock: TIMER0 counts microseconds (16 MHz / 2^4, 32 bits) and port_millis() turns its advance
 * since the last call into milliseconds (a counter read loses no time when interrupts come late;
 * it must be called at least every 71 minutes, the counter's wrap). SysTick interrupts every
 * millisecond, only to wake the main loop from WFI. */
#include <stdbool.h>

#include "cortex_m.h"
#include "port.h"

#define REG(address) CORTEX_M_REG(address)

#define UART0 0x40002000u
#define UART_STARTRX REG(UART0 + 0x000u)
#define UART_STARTTX REG(UART0 + 0x008u)
#define UART_RXDRDY REG(UART0 + 0x108u)
#define UART_TXDRDY REG(UART0 + 0x11Cu)
#define UART_INTENSET REG(UART0 + 0x304u)
#define UART_ENABLE REG(UART0 + 0x500u)
#define UART_PSELTXD REG(UART0 + 0x50Cu)
#define UART_PSELRXD REG(UART0 + 0x514u)
#define UART_RXD REG(UART0 + 0x518u)
#define UART_TXD REG(UART0 + 0x51Cu)
#define UART_BAUDRATE REG(UART0 + 0x524u)
#define UART_ENABLE_ON 4u
#define UART_INT_RXDRDY (1u << 2)
#define UART_BAUD_115200 0x01D7E000u
#define TX_PIN 24u
#define RX_PIN 25u

#define TIMER0 0x40008000u
#define TIMER_START REG(TIMER0 + 0x000u)
#define TIMER_CAPTURE0 REG(TIMER0 + 0x040u)
#define TIMER_MODE REG(TIMER0 + 0x504u)
#define TIMER_BITMODE REG(TIMER0 + 0x508u)
#define TIMER_PRESCALER REG(TIMER0 + 0x510u)
#define TIMER_CC0 REG(TIMER0 + 0x540u)
#define TIMER_BITMODE_32 3u
#define TIMER_PRESCALER_1MHZ 4u

#define CPU_HZ 16000000u

static uint32_t clock_last_us;
static uint32_t clock_rest_us; /* below 1000 */
static uint32_t clock_ms;
static volatile uint8_t rx_paused; /* the receive interrupt is masked: the application was full */

void port_init(void)
{
    TIMER_MODE = 0; /* timer */
    TIMER_BITMODE = TIMER_BITMODE_32;
    TIMER_PRESCALER = TIMER_PRESCALER_1MHZ;
    TIMER_START = 1;

    UART_PSELTXD = TX_PIN;
    UART_PSELRXD = RX_PIN;
    UART_BAUDRATE = UART_BAUD_115200;
    UART_ENABLE = UART_ENABLE_ON;
    UART_STARTTX = 1;
    UART_STARTRX = 1;
    UART_RXDRDY = 0;
    UART_INTENSET = UART_INT_RXDRDY;
    cortex_m_enable_irq(PORT_UART_IRQN);
    cortex_m_start_tick(CPU_HZ / 1000u);
}

/* Hands the UART's waiting bytes to the application while it has room. Returns false when some had
 * to stay in the UART. Only one context runs it at a time: the interrupt, or port_idle() while the
 * interrupt is masked. */
static bool take_received(void)
{
    while (UART_RXDRDY) {
        if (port_uart_room() == 0u) {
            return false;
        }
        /* Clear the event before reading RXD: a byte that arrives meanwhile raises it again. */
        UART_RXDRDY = 0;
        port_uart_received((uint8_t)UART_RXD);
    }
    return true;
}

void port_uart_irq_handler(void)
{
    if (!take_received()) {
        cortex_m_mask_irq(PORT_UART_IRQN); /* until port_idle(), after the main loop has polled */
        rx_paused = 1u;
    }
}

void port_systick_handler(void)
{
    /* Nothing to do: the tick only wakes the main loop from port_idle(). */
}

uint32_t port_millis(void)
{
    TIMER_CAPTURE0 = 1;
    uint32_t now_us = TIMER_CC0;
    uint32_t elapsed_us = now_us - clock_last_us + clock_rest_us;
    clock_last_us = now_us;
    clock_ms += elapsed_us / 1000u;
    clock_rest_us = elapsed_us % 1000u;
    return clock_ms;
}

void port_uart_write(const uint8_t *data, size_t size)
{
    for (size_t i = 0; i < size; i++) {
        UART_TXDRDY = 0;
        UART_TXD = data[i];
        while (!UART_TXDRDY) {
        }
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
