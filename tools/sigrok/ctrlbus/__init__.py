# SPDX-License-Identifier: MIT
'''
SLAMWARE Control Bus (ctrlbus): the UART protocol between a SLAMWARE Core
(master) and a robot base (slave), 115200 8N1.

Stack it on the 'uart' decoder. By default the UART's RX line carries the
Core's requests (probe the base's RX pin) and TX the base's answers; the
'requests' option swaps them.

Shows, per direction: the parts of every frame (flag, LEN, CMD, payload,
checksum), each request and answer by name with its fields and units
(answers paired with the request they answer), and what is not a frame:
garbage, checksum errors (found and expected checksum), oversize frames,
inter-byte timeouts and empty frames, with the stream decoder rules of
docs/protocol.md section 7.

Installing for PulseView and sigrok-cli: tools/sigrok/README.md.
'''

from .pd import Decoder
