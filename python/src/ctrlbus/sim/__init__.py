# SPDX-License-Identifier: MIT
"""The simulated base's world: a differential-drive robot in a 2-D room (physics, no protocol).

See docs/simulator.md. The protocol side (answering Control Bus requests from this world) is
built on top of `World` and never the other way round.
"""

from ctrlbus.sim.description import BaseDescription, load_base_description
from ctrlbus.sim.room import Room, load_room
from ctrlbus.sim.world import World

__all__ = ["BaseDescription", "Room", "World", "load_base_description", "load_room"]
