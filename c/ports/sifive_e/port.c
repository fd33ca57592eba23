/* SPDX-License-Identifier: MIT */
/* c/ports/port.h for the SiFive FE310 (HiFive1 class, RV32IMAC), as `qemu-system-riscv32 -M
 * sifive_e` models it (UART0 is QEMU's serial 0). Start-up and linker script are picolibc's
 * (crt0 copies .data and zeroes .bss); the Makefile places flash and RAM with --defsym.
 *
 * UART: UART0 at 0x10013000; its receive-watermark interrupt (one byte or more waiting) reaches
 * the core through the PLIC (source 3) as a machine external interrupt, whose handler hands each
 * byte to port_uart_received() while port_uart_room() allows; otherwise it masks the interrupt and
 * leaves the bytes in the UART's FIFO for port_idle() (port.h says why). 115200 8N1 needs the
 * divisor of the bus clock: 16 MHz on QEMU's model, UART_DIVISOR below.
 * Clock: the CLINT's 64-bit mtime; port_millis() turns its advance since the last call into
 * milliseconds (a counter read loses no time when interrupts come late). The machine timer
 * interrupts every millisecond (mtimecmp), only to wake the main loop from WFI.
 *
 * MTIME_HZ is mtime's rate: 32768 Hz on the chip (the low-frequency clock), 10 MHz in QEMU's
 * model, so the image for QEMU is built with -DMTIME_HZ=10000000u. */
#include <stdbool.h>

#include "port.h"

#ifndef MTIME_HZ
#define MTIME_HZ 32768u
#endif

#define REG(address) (*(volatile uint32_t *)(uintptr_t)(address))

#define UART0 0x10013000u
#define UART_TXDATA REG(UART0 + 0x00u)
#define UART_RXDATA REG(UART0 + 0x04u)
#define UART_TXCTRL REG(UART0 + 0x08u)
#define UART_RXCTRL REG(UART0 + 0x0Cu)
#define UART_IE REG(UART0 + 0x10u)
#define UART_IP REG(UART0 + 0x14u)
#define UART_DIV REG(UART0 + 0x18u)
#define UART_TXDATA_FULL (1u << 31)
#define UART_ENABLE 1u
#define UART_IE_RXWM (1u << 1)
#define UART_IP_RXWM (1u << 1) /* pending: more bytes waiting than the watermark (0) */
#define UART_DIVISOR (16000000u / 115200u - 1u)

#define PLIC 0x0C000000u
#define UART0_SOURCE 3u
#define PLIC_PRIORITY(source) REG(PLIC + 4u * (source))
#define PLIC_ENABLE REG(PLIC + 0x2000u)
#define PLIC_THRESHOLD REG(PLIC + 0x200000u)
#define PLIC_CLAIM REG(PLIC + 0x200004u)

#define CLINT 0x02000000u
#define MTIMECMP_LO REG(CLINT + 0x4000u)
#define MTIMECMP_HI REG(CLINT + 0x4004u)
#define MTIME_LO REG(CLINT + 0xBFF8u)

#define MIE_MTIE (1u << 7)  /* machine timer */
#define MIE_MEIE (1u << 11) /* machine external (the PLIC) */
#define MSTATUS_MIE (1u << 3)
#define MCAUSE_INTERRUPT (1u << 31)
#define MCAUSE_TIMER 7u
#define MCAUSE_EXTERNAL 11u

/* CSR instructions, whatever -march says: GCC 12 counts them as the Zicsr extension, and the
 * picolibc multilibs Debian ships are built for plain rv32imac. */
#define CSR(instruction) ".option push\n.option arch, +zicsr\n" instruction "\n.option pop"

/* mtime counts per wake-up tick (about a millisecond; at least 1) */
#define TICK_COUNTS (MTIME_HZ / 1000u > 0u ? MTIME_HZ / 1000u : 1u)

static uint32_t clock_last_count; /* the low word is enough: read at least every 2^32 counts */
static uint32_t clock_rest;       /* counts * 1000 not yet a millisecond, below MTIME_HZ */
static uint32_t clock_ms;
static volatile uint8_t rx_paused; /* the receive interrupt is masked: the application was full */

static void set_next_tick(void)
{
    /* Low word only and the high word maxed first, so that no half-written compare value fires:
     * a wake-up one 2^32-count wrap late is harmless. */
    MTIMECMP_HI = 0xFFFFFFFFu;
    MTIMECMP_LO = MTIME_LO + TICK_COUNTS;
    MTIMECMP_HI = 0;
}

/* Hands the UART's waiting bytes to the application while it has room. Returns false when some had
 * to stay in the FIFO. Only one context runs it at a time: the interrupt, or port_idle() while the
 * interrupt is masked. */
static bool take_received(void)
{
    while (UART_IP & UART_IP_RXWM) { /* a byte waits: IP tells without taking it */
        if (port_uart_room() == 0u) {
            return false;
        }
        port_uart_received((uint8_t)UART_RXDATA);
    }
    return true;
}

__attribute__((interrupt("machine"), aligned(4))) static void trap_handler(void)
{
    uint32_t cause;
    __asm__ volatile(CSR("csrr %0, mcause") : "=r"(cause));
    if (cause == (MCAUSE_INTERRUPT | MCAUSE_TIMER)) {
        set_next_tick(); /* the tick only wakes the main loop from port_idle() */
    } else if (cause == (MCAUSE_INTERRUPT | MCAUSE_EXTERNAL)) {
        uint32_t source = PLIC_CLAIM;
        if (!take_received()) {
            UART_IE = 0; /* until port_idle(), after the main loop has polled */
            rx_paused = 1u;
        }
        PLIC_CLAIM = source; /* complete */
    } else {
        for (;;) { /* an exception: park here, where a debugger finds it */
        }
    }
}

void port_init(void)
{
    UART_DIV = UART_DIVISOR;
    UART_TXCTRL = UART_ENABLE;
    UART_RXCTRL = UART_ENABLE; /* watermark 0: interrupt while one byte or more waits */
    UART_IE = UART_IE_RXWM;
    PLIC_PRIORITY(UART0_SOURCE) = 1;
    PLIC_ENABLE = 1u << UART0_SOURCE;
    PLIC_THRESHOLD = 0;

    clock_last_count = MTIME_LO;
    set_next_tick();
    __asm__ volatile(CSR("csrw mtvec, %0") ::"r"((uintptr_t)trap_handler)); /* direct mode */
    __asm__ volatile(CSR("csrs mie, %0") ::"r"(MIE_MTIE | MIE_MEIE));
    __asm__ volatile(CSR("csrs mstatus, %0") ::"r"(MSTATUS_MIE));
}

uint32_t port_millis(void)
{
    uint32_t count = MTIME_LO;
    uint64_t scaled = (uint64_t)(count - clock_last_count) * 1000u + clock_rest;
    clock_last_count = count;
    clock_ms += (uint32_t)(scaled / MTIME_HZ);
    clock_rest = (uint32_t)(scaled % MTIME_HZ);
    return clock_ms;
}

void port_uart_write(const uint8_t *data, size_t size)
{
    for (size_t i = 0; i < size; i++) {
        while (UART_TXDATA & UART_TXDATA_FULL) {
        }
        UART_TXDATA = data[i];
    }
}

void port_idle(void)
{
    if (rx_paused && take_received()) { /* the interrupt is masked: nothing else takes bytes */
        rx_paused = 0u;
        UART_IE = UART_IE_RXWM; /* a byte that came after the last look raises it at once */
    }
    __asm__ volatile("wfi" ::: "memory");
}
