/* SPDX-License-Identifier: MIT */
/* Runs an ATmega328P image in simavr (libsimavr), with USART0 on a pseudo-terminal: the bench for
 * the Uno chip image (minimal_base.elf), whose receive interrupt and idle sleep QEMU 7.2's AVR
 * model cannot run (c/ports/uno/port.c says why). A host program, built by c/ports/Makefile.
 *
 *   simavr_uno IMAGE [--ram-dump FILE]
 *
 * Prints one line, "uart0 PATH" (the pty to open; the image sets 115200 8N1), on stdout once the
 * image runs, then runs it until SIGINT or SIGTERM, or until the core stops (exit status 1: it
 * crashed or halted). With --ram-dump, the data memory (registers, I/O and the 2 KB of RAM, from
 * address 0 to RAMEND) is written to FILE at the end, so that a test can read how deep the stack
 * went (the image paints its free RAM at start-up).
 *
 * The bridge between the pty and the USART is ours, not simavr's uart_pty part: that one stalls
 * for good once a burst fills both its buffer and the USART's (a frame of about 580 bytes). Ours
 * runs in the simulation's own thread, every 100 us of simulated time: what the pty holds goes
 * to the USART while simavr says its receive FIFO has room (its XON/XOFF signals), and what the
 * USART sends goes to the pty as it leaves, at the baud rate simavr models.
 *
 * Time: simavr runs the core as fast as the host allows, and sleeps in real time while the image
 * sleeps (SLEEP until the next interrupt), which this image does between its 1 ms timer wakes; so
 * its clock runs close to the wall clock, a little ahead while the core is busy. */
#define _DEFAULT_SOURCE    /* cfmakeraw */
#define _XOPEN_SOURCE 600 /* posix_openpt, grantpt, unlockpt, ptsname */
#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <termios.h>
#include <unistd.h>

#include "avr_uart.h"
#include "sim_avr.h"
#include "sim_elf.h"
#include "sim_io.h"
#include "sim_time.h"

#define MCU "atmega328p"
#define CLOCK_HZ 16000000u
#define RAM_END 0x8FFu         /* ATmega328P's last data-memory address */
#define BRIDGE_PERIOD_US 100u  /* how often the bridge looks at the pty */
#define WRITE_WAIT_MS 1000     /* how long a byte for the pty waits for a reader */

typedef struct {
    avr_t *avr;
    int pty;          /* the master side; the image's peer opens the slave */
    avr_irq_t *input; /* bytes for the USART's receiver */
    int room;         /* simavr's XON (1) / XOFF (0) for the receive FIFO */
    uint8_t pending[256];
    size_t pending_at, pending_len;
    unsigned long dropped; /* bytes for the pty that no reader took */
} bridge_t;

static volatile sig_atomic_t stop_requested;

static void request_stop(int signal_number)
{
    (void)signal_number;
    stop_requested = 1;
}

static int fail(const char *what, const char *detail)
{
    fprintf(stderr, "simavr_uno: %s: %s\n", what, detail);
    return 2;
}

static void receiver_has_room(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    (void)value;
    ((bridge_t *)param)->room = 1;
}

static void receiver_is_full(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    ((bridge_t *)param)->room = value == 0u;
}

/* A byte the USART has sent: to the pty, waiting a while for a slow reader. */
static void transmitted(struct avr_irq_t *irq, uint32_t value, void *param)
{
    (void)irq;
    bridge_t *bridge = param;
    uint8_t byte = (uint8_t)value;
    for (;;) {
        ssize_t written = write(bridge->pty, &byte, 1);
        if (written == 1) {
            return;
        }
        if (written < 0 && errno == EAGAIN) {
            struct pollfd wait = {.fd = bridge->pty, .events = POLLOUT};
            if (poll(&wait, 1, WRITE_WAIT_MS) > 0) {
                continue;
            }
        } else if (written < 0 && errno == EINTR) {
            continue;
        }
        bridge->dropped++; /* nobody reads the pty */
        return;
    }
}

/* Every BRIDGE_PERIOD_US: the pty's bytes to the USART while its FIFO has room. */
static avr_cycle_count_t pump(struct avr_t *avr, avr_cycle_count_t when, void *param)
{
    bridge_t *bridge = param;
    if (bridge->pending_at == bridge->pending_len) {
        ssize_t got = read(bridge->pty, bridge->pending, sizeof bridge->pending);
        bridge->pending_at = 0;
        bridge->pending_len = got > 0 ? (size_t)got : 0u; /* EAGAIN, or EIO with no reader */
    }
    while (bridge->room && bridge->pending_at < bridge->pending_len) {
        avr_raise_irq(bridge->input, bridge->pending[bridge->pending_at++]);
    }
    return when + avr_usec_to_cycles(avr, BRIDGE_PERIOD_US);
}

static int open_pty(bridge_t *bridge, const char **slave)
{
    int pty = posix_openpt(O_RDWR | O_NOCTTY | O_NONBLOCK);
    if (pty < 0 || grantpt(pty) != 0 || unlockpt(pty) != 0 || (*slave = ptsname(pty)) == NULL) {
        return fail("cannot make a pty", strerror(errno));
    }
    struct termios raw;
    if (tcgetattr(pty, &raw) == 0) {
        cfmakeraw(&raw); /* binary frames: no echo, no line editing, no flow-control bytes */
        (void)tcsetattr(pty, TCSANOW, &raw);
    }
    bridge->pty = pty;
    return 0;
}

static void connect_uart(bridge_t *bridge)
{
    avr_t *avr = bridge->avr;
    uint32_t flags = 0;
    avr_ioctl(avr, AVR_IOCTL_UART_GET_FLAGS('0'), &flags);
    flags &= ~(uint32_t)AVR_UART_FLAG_STDIO; /* its bytes are frames, not console lines */
    avr_ioctl(avr, AVR_IOCTL_UART_SET_FLAGS('0'), &flags);
    bridge->input = avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_INPUT);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUTPUT),
                            transmitted, bridge);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XON),
                            receiver_has_room, bridge);
    avr_irq_register_notify(avr_io_getirq(avr, AVR_IOCTL_UART_GETIRQ('0'), UART_IRQ_OUT_XOFF),
                            receiver_is_full, bridge);
    bridge->room = 1;
    avr_cycle_timer_register_usec(avr, BRIDGE_PERIOD_US, pump, bridge);
}

static int dump_ram(const avr_t *avr, const char *path)
{
    FILE *file = fopen(path, "wb");
    if (file == NULL) {
        return fail("cannot write the RAM dump", path);
    }
    size_t written = fwrite(avr->data, 1, RAM_END + 1u, file);
    if (fclose(file) != 0 || written != RAM_END + 1u) {
        return fail("cannot write the RAM dump", path);
    }
    return 0;
}

static void restore_stdout(int saved)
{
    fflush(stdout);
    if (saved >= 0) {
        (void)dup2(saved, STDOUT_FILENO);
        close(saved);
    }
}

int main(int argc, char **argv)
{
    const char *image = NULL;
    const char *ram_dump = NULL;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--ram-dump") == 0 && i + 1 < argc) {
            ram_dump = argv[++i];
        } else if (argv[i][0] != '-' && image == NULL) {
            image = argv[i];
        } else {
            return fail("usage", "simavr_uno IMAGE [--ram-dump FILE]");
        }
    }
    if (image == NULL) {
        return fail("usage", "simavr_uno IMAGE [--ram-dump FILE]");
    }
    /* simavr reports what it loads on stdout: to stderr with it, so stdout carries our line only. */
    fflush(stdout);
    int saved_stdout = dup(STDOUT_FILENO);
    (void)dup2(STDERR_FILENO, STDOUT_FILENO);
    elf_firmware_t firmware;
    memset(&firmware, 0, sizeof firmware);
    if (elf_read_firmware(image, &firmware) != 0) {
        return fail("cannot read the image", image);
    }
    static bridge_t bridge;
    bridge.avr = avr_make_mcu_by_name(MCU);
    if (bridge.avr == NULL || avr_init(bridge.avr) != 0) {
        return fail("simavr has no model of", MCU);
    }
    firmware.frequency = CLOCK_HZ;
    avr_load_firmware(bridge.avr, &firmware);
    restore_stdout(saved_stdout);
    const char *slave = NULL;
    if (open_pty(&bridge, &slave) != 0) {
        return 2;
    }
    connect_uart(&bridge);
    printf("uart0 %s\n", slave);
    fflush(stdout);

    struct sigaction action;
    memset(&action, 0, sizeof action);
    action.sa_handler = request_stop;
    sigaction(SIGINT, &action, NULL);
    sigaction(SIGTERM, &action, NULL);

    int state = cpu_Running;
    while (!stop_requested && state != cpu_Done && state != cpu_Crashed) {
        state = avr_run(bridge.avr);
    }
    int status = 0;
    if (state == cpu_Done || state == cpu_Crashed) {
        fprintf(stderr, "simavr_uno: the core stopped (%s) at pc 0x%04x\n",
                state == cpu_Crashed ? "crashed" : "halted", (unsigned)bridge.avr->pc);
        status = 1;
    }
    if (bridge.dropped != 0u) {
        fprintf(stderr, "simavr_uno: %lu bytes sent while nobody read the pty\n", bridge.dropped);
    }
    if (ram_dump != NULL && dump_ram(bridge.avr, ram_dump) != 0) {
        return 2;
    }
    return status;
}
