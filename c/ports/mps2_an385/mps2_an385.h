/* SPDX-License-Identifier: MIT */
/* Registers of the parts of QEMU's mps2-an385 board (ARM AN385: Cortex-M3 on the MPS2 FPGA) that
 * its port (port.c) uses. Addresses and interrupt numbers are those of QEMU's model (hw/arm/mps2.c),
 * which follows the AN385 application note. */
#ifndef CTRLBUS_PORT_MPS2_AN385_H
#define CTRLBUS_PORT_MPS2_AN385_H

#include <stdint.h>

#define MPS2_REG(addr) (*(volatile uint32_t *)(uintptr_t)(addr))

/* Peripheral clock of the APB UARTs and the CPU clock that SysTick counts. */
#define MPS2_SYSCLK_HZ 25000000u

/* CMSDK APB UART0 (the first -serial of QEMU). */
#define MPS2_UART0_BASE 0x40004000u
/* AN385 interrupt lines: UART0 RX is IRQ 0 and UART0 TX is IRQ 1; the overrun interrupts of
 * UARTs 0-2 share IRQ 12. */
#define MPS2_UART0_RX_IRQN 0u
#define MPS2_UART0_TX_IRQN 1u
#define MPS2_UART_OVERRUN_IRQN 12u
/* AN385 wires 32 external interrupts to the NVIC. */
#define MPS2_IRQ_COUNT 32u

/* CMSDK APB UART register offsets and bits (ARM DDI0479, "APB UART"). */
#define CMSDK_UART_DATA(base) MPS2_REG((base) + 0x00u)
#define CMSDK_UART_STATE(base) MPS2_REG((base) + 0x04u)
#define CMSDK_UART_CTRL(base) MPS2_REG((base) + 0x08u)
#define CMSDK_UART_INTSTATUS(base) MPS2_REG((base) + 0x0Cu) /* read: status, write 1: clear */
#define CMSDK_UART_BAUDDIV(base) MPS2_REG((base) + 0x10u)

#define CMSDK_UART_STATE_TX_FULL 0x01u
#define CMSDK_UART_STATE_RX_FULL 0x02u
#define CMSDK_UART_STATE_TX_OVERRUN 0x04u
#define CMSDK_UART_STATE_RX_OVERRUN 0x08u

#define CMSDK_UART_CTRL_TX_EN 0x01u
#define CMSDK_UART_CTRL_RX_EN 0x02u
#define CMSDK_UART_CTRL_TX_IRQ_EN 0x04u
#define CMSDK_UART_CTRL_RX_IRQ_EN 0x08u

#define CMSDK_UART_INT_TX 0x01u
#define CMSDK_UART_INT_RX 0x02u

/* CMSDK APB timer 0 (ARM DDI0479, "APB timer"): a 32-bit down-counter at the peripheral clock,
 * reloaded from RELOAD when it reaches zero. */
#define MPS2_TIMER0_BASE 0x40000000u
#define CMSDK_TIMER_CTRL(base) MPS2_REG((base) + 0x00u)
#define CMSDK_TIMER_VALUE(base) MPS2_REG((base) + 0x04u)
#define CMSDK_TIMER_RELOAD(base) MPS2_REG((base) + 0x08u)
#define CMSDK_TIMER_CTRL_ENABLE 0x1u

/* The core's SysTick and NVIC registers: ../ports/cortex_m/cortex_m.h. */

/* Application interrupt and reset control: writing VECTKEY | SYSRESETREQ resets the chip. */
#define SCB_AIRCR MPS2_REG(0xE000ED0Cu)
#define SCB_AIRCR_VECTKEY 0x05FA0000u
#define SCB_AIRCR_SYSRESETREQ 0x4u

#endif
