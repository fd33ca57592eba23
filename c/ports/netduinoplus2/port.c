/* SPDX-License-Identifier: MIT */
/* c/ports/port.h for the Netduino Plus 2 (STM32F405RG, Cortex-M4F), as `qemu-system-arm -M
 * netduinoplus2` models it (USART1 is QEMU's serial 0). The core runs from the reset clock, the
 * 16 MHz internal oscillator (HSI): no PLL set-up, which a base that needs speed adds.
 *
 * UART: USART1 on PA9 (TX) / PA10 (RX), alternate function 7, 115200 8N1; the RXNE interrupt
 * (IRQ 37) hands each byte to port_uart_received() while port_uart_room() allows (port.h).
 * Clock: TIM2 (32 bits) counts at 100 kHz and port_millis() turns its advance since the last call
 * into milliseconds (a counter read loses no time when interrupts come late). SysTick interrupts
 * every millisecond, only to wake the main loop from WFI.
 *
 * STM32_TIMER_HZ is TIM2's input clock: 16 MHz on the chip with this set-up; QEMU's timer model
 * counts at 1 GHz whatever the RCC says, so the image for QEMU is built with
 * -DSTM32_TIMER_HZ=1000000000u. */
#include <stdbool.h>

#include "cortex_m.h"
#include "port.h"

#ifndef STM32_TIMER_HZ
#define STM32_TIMER_HZ 16000000u
#endif

#define REG(address) CORTEX_M_REG(address)

#define RCC 0x40023800u
#define RCC_AHB1ENR REG(RCC + 0x30u)
#define RCC_APB1ENR REG(RCC + 0x40u)
#define RCC_APB2ENR REG(RCC + 0x44u)
#define RCC_AHB1ENR_GPIOA (1u << 0)
#define RCC_APB1ENR_TIM2 (1u << 0)
#define RCC_APB2ENR_USART1 (1u << 4)

#define GPIOA 0x40020000u
#define GPIOA_MODER REG(GPIOA + 0x00u)
#define GPIOA_AFRH REG(GPIOA + 0x24u)
#define MODER_AF(pin) (2u << (2u * (pin)))
#define MODER_MASK(pin) (3u << (2u * (pin)))
#define AFRH_AF(pin, af) ((uint32_t)(af) << (4u * ((pin) - 8u)))
#define AFRH_MASK(pin) (15u << (4u * ((pin) - 8u)))

#define USART1 0x40011000u
#define USART_SR REG(USART1 + 0x00u)
#define USART_DR REG(USART1 + 0x04u)
#define USART_BRR REG(USART1 + 0x08u)
#define USART_CR1 REG(USART1 + 0x0Cu)
#define USART_SR_RXNE (1u << 5)
#define USART_SR_TXE (1u << 7)
#define USART_CR1_UE (1u << 13)
#define USART_CR1_RXNEIE (1u << 5)
#define USART_CR1_TE (1u << 3)
#define USART_CR1_RE (1u << 2)

#define TIM2 0x40000000u
#define TIM_CR1 REG(TIM2 + 0x00u)
#define TIM_EGR REG(TIM2 + 0x14u)
#define TIM_CNT REG(TIM2 + 0x24u)
#define TIM_PSC REG(TIM2 + 0x28u)
#define TIM_ARR REG(TIM2 + 0x2Cu)
#define TIM_CR1_CEN (1u << 0)
#define TIM_EGR_UG (1u << 0)

#define CPU_HZ 16000000u /* HSI */
#define BAUD 115200u
#define COUNTS_PER_MS 100u /* TIM2 at 100 kHz */

static uint32_t clock_last_count;
static uint32_t clock_rest; /* counts below a millisecond */
static uint32_t clock_ms;
static volatile uint8_t rx_paused; /* the receive interrupt is masked: the application was full */

void port_init(void)
{
    RCC_AHB1ENR |= RCC_AHB1ENR_GPIOA;
    RCC_APB1ENR |= RCC_APB1ENR_TIM2;
    RCC_APB2ENR |= RCC_APB2ENR_USART1;

    TIM_PSC = STM32_TIMER_HZ / (COUNTS_PER_MS * 1000u) - 1u;
    TIM_ARR = 0xFFFFFFFFu;
    TIM_EGR = TIM_EGR_UG; /* load the prescaler now */
    TIM_CR1 = TIM_CR1_CEN;

    GPIOA_MODER = (GPIOA_MODER & ~(MODER_MASK(9u) | MODER_MASK(10u))) | MODER_AF(9u) | MODER_AF(10u);
    GPIOA_AFRH = (GPIOA_AFRH & ~(AFRH_MASK(9u) | AFRH_MASK(10u))) | AFRH_AF(9u, 7u) | AFRH_AF(10u, 7u);
    USART_BRR = (CPU_HZ + BAUD / 2u) / BAUD; /* APB2 = HSI after reset */
    USART_CR1 = USART_CR1_UE | USART_CR1_TE | USART_CR1_RE | USART_CR1_RXNEIE;
    cortex_m_enable_irq(PORT_UART_IRQN);
    cortex_m_start_tick(CPU_HZ / 1000u);
}

/* Hands the UART's waiting bytes to the application while it has room. Returns false when one had
 * to stay in the UART. Only one context runs it at a time: the interrupt, or port_idle() while the
 * interrupt is masked. */
static bool take_received(void)
{
    while (USART_SR & USART_SR_RXNE) {
        if (port_uart_room() == 0u) {
            return false;
        }
        port_uart_received((uint8_t)USART_DR); /* reading DR clears RXNE */
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
    uint32_t count = TIM_CNT;
    uint32_t elapsed = count - clock_last_count + clock_rest;
    clock_last_count = count;
    clock_ms += elapsed / COUNTS_PER_MS;
    clock_rest = elapsed % COUNTS_PER_MS;
    return clock_ms;
}

void port_uart_write(const uint8_t *data, size_t size)
{
    for (size_t i = 0; i < size; i++) {
        while (!(USART_SR & USART_SR_TXE)) {
        }
        USART_DR = data[i];
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
