/* SPDX-License-Identifier: MIT */
/* Board bring-up probe: every byte received on UART0 is sent back.
 *
 * It proves the path the base firmware relies on (vector table, .data/.bss start-up, the UART0
 * RX interrupt, the main loop that sleeps between interrupts) without the protocol stack. The
 * interrupt handler queues bytes in a single-producer/single-consumer ring; the main loop drains
 * it. */
#include <stdint.h>

#include "board.h"

#define ECHO_RING_SIZE 256u /* a power of two, so the free-running indices wrap cleanly */

typedef struct {
    uint8_t bytes[ECHO_RING_SIZE];
    volatile uint32_t head; /* written by the interrupt only */
    volatile uint32_t tail; /* written by the main loop only */
    volatile uint32_t dropped;
} echo_ring_t;

static echo_ring_t ring;

static void on_rx_byte(void *context, uint8_t byte)
{
    echo_ring_t *r = context;
    uint32_t head = r->head;
    if (head - r->tail >= ECHO_RING_SIZE) {
        r->dropped = r->dropped + 1u;
        return;
    }
    r->bytes[head % ECHO_RING_SIZE] = byte;
    r->head = head + 1u;
}

int main(void)
{
    board_init(on_rx_byte, &ring);
    for (;;) {
        uint32_t tail = ring.tail;
        if (tail == ring.head) {
            board_wait_for_interrupt();
            continue;
        }
        uint8_t byte = ring.bytes[tail % ECHO_RING_SIZE];
        ring.tail = tail + 1u;
        board_uart_write(&byte, 1);
    }
}
