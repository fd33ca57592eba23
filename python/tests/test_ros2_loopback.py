# SPDX-License-Identifier: MIT
"""DDS stays on this machine: the bridge (`--loopback`) and the tests' own participants select
only the `lo` interface and send only to 127.0.0.1, as Cyclone DDS's own discovery trace shows.

Every address a participant sends to is in its trace: the peers it adds, the locators each
discovered participant announces, and the address sets of its writers. The lines that merely list
the host's interfaces or the configured (unused, multicast being off) multicast addresses are the
only others.
"""

from __future__ import annotations

import re
from pathlib import Path

from ros2_support import Node, sim_port, start_bridge, start_sim, unique_domain, wait_for

from ctrlbus.ros2 import msgs

ADDRESS = re.compile(r"udp6?/([0-9a-fA-F.:\[\]]+?)(?::\d+)?(?:@\d+)?(?=[\s,)(]|$)")
# lines that describe the host or the configuration, not where anything is sent
NOT_DESTINATIONS = ("config:", " interfaces: ", " SPDP MC: ", " default MC: ")


def destinations(trace: str) -> set[str]:
    found: set[str] = set()
    for line in trace.splitlines():
        if any(marker in line for marker in NOT_DESTINATIONS):
            continue
        found.update(match.group(1) for match in ADDRESS.finditer(line))
    return found


def check_trace(path: Path) -> None:
    trace = path.read_text(errors="replace")
    assert re.search(r"selected interfaces: lo \(", trace), f"{path}: lo is not the only interface"
    assert "Domain/General/AllowMulticast/#text: false" in trace
    assert "ddsi_rebuild_writer_addrset" in trace, f"{path}: no address sets traced"
    assert destinations(trace) == {"127.0.0.1"}


def test_the_addresses_are_found_in_a_trace_line() -> None:
    line = "dq.builtin: SPDP ST0 x NEW (data udp/127.0.0.1:22163@1 meta udp/10.1.2.3:22162@1)"
    assert destinations(line) == {"127.0.0.1", "10.1.2.3"}
    assert destinations("python: SPDP MC: udp/239.255.0.1") == set()


def test_bridge_and_node_discover_each_other_on_loopback_only(tmp_path: Path) -> None:
    sim = start_sim(seed=1)
    domain = unique_domain()
    node_trace, bridge_trace = tmp_path / "node.trace", tmp_path / "bridge.trace"
    node = Node(domain, node_trace)
    odom = node.subscribe("rt/odom", msgs.Odometry)
    bridge = start_bridge(sim_port(sim), domain, tmp_path, "--dds-trace", str(bridge_trace))
    try:
        wait_for("odometry", lambda: len(odom) > 5)
        node.publish("rt/cmd_vel", msgs.Twist())
    finally:
        bridge.stop()
        sim.close()
    check_trace(node_trace)
    check_trace(bridge_trace)
