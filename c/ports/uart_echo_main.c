/* SPDX-License-Identifier: MIT */
/* Board bring-up probe for a new port: every byte received on the UART is sent back.
 *
 * It proves the path a base relies on (vector table, .data/.bss start-up, the UART receive
 * interrupt, the main loop that sleeps between interrupts) through port.h, without the protocol
 * stack. The interrupt queues bytes in a single-producer/single-consumer ring; the main loop
 * drains it. */
#include <stdint.h>

#include "port.h"

#define ECHO_RING_SIZE 256u /* a power of two, so the free-running indices wrap cleanly */

typedef struct {
    uint8_t bytes[ECHO_RING_SIZE];
    volatile uint32_t head; /* written by the interrupt only */
    volatile uint32_t tail; /* written by the main loop only */
    volatile uint32_t dropped;
} echo_ring_t;

static echo_ring_t ring;

void port_uart_received(uint8_t byte)
{
    echo_ring_t *r = &ring;
    uint32_t head = r->head;
    if (head - r->tail >= ECHO_RING_SIZE) {
        r->dropped = r->dropped + 1u;
        return;
    }
    r->bytes[head % ECHO_RING_SIZE] = byte;
    r->head = head + 1u;
}

size_t port_uart_room(void)
{
    return ECHO_RING_SIZE - (size_t)(ring.head - ring.tail);
}

int main(void)
{
    port_init();
    for (;;) {
        uint32_t tail = ring.tail;
        if (tail == ring.head) {
            port_idle();
            continue;
        }
        uint8_t byte = ring.bytes[tail % ECHO_RING_SIZE];
        ring.tail = tail + 1u;
        port_uart_write(&byte, 1);
    }
}
