# SPDX-License-Identifier: MIT
"""`ctrlbus ros2`: the Core emulator's session bridged to ROS 2 topics over DDS (docs/ros2.md).

    ctrlbus ros2 --port URL [--domain N] [--namespace NS] [--distro humble|jazzy] [--stamped]
                 [--cmd-vel-timeout S] [--odom-frame F] [--base-frame F] [--rates NAME=HZ,...]
                 [--range SLOT=sonar|ir:FOV_DEG:MIN_M:MAX_M ...] [--core-rates NAME=HZ,...]
                 [--rosbag DIR] [--loopback] [--connect-timeout S] [--duration S]

Needs the ros2 extra (`pip install 'ctrlbus[ros2]'`): without it, one line naming the extra and
exit code 2. Exit codes otherwise as `ctrlbus core`: 0 after Ctrl-C, SIGTERM or --duration; 2 for
a bad option, a port that cannot be opened or a base that does not answer within --connect-timeout;
1 if the Core or the bridge failed.
"""

from __future__ import annotations

import argparse
import os
import sys
import threading
import time
from typing import Any

from ctrlbus.cli.common import add_baud_argument, add_port_argument, positive_number, stop_on_signals
from ctrlbus.constants import Profile
from ctrlbus.core import CoreConfig, CoreRunner, CoreSession, PollRates, byte_time_for_baud
from ctrlbus.errors import ProtocolTimeout, UsageError
from ctrlbus.link import Link
from ctrlbus.ports import open_link
from ctrlbus.ros2.dds import DISTROS, check_domain, dds_config, require_cyclonedds

__all__ = ["DESCRIPTION", "add_bridge_arguments", "maker_from_args", "refuse_existing_bag", "register", "run"]

DEFAULT_CONNECT_TIMEOUT_S = 5.0

DESCRIPTION = """\
Run the Core emulator against a base and bridge it to ROS 2: cmd_vel (geometry_msgs/Twist, or
TwistStamped with --stamped) drives the base, clamped to its limits and stopped when no command
comes for --cmd-vel-timeout seconds; odom, tf, tf_static, battery_state, one sensor_msgs/Range
per distance sensor, bumper_cloud (sensor_msgs/PointCloud2 at the pressed bumpers and cliffs) and
diagnostics are published; dock, undock, reset_odometry (std_msgs/Empty) and emergency_stop
(std_msgs/Bool: true latches, false releases) are commands. No ROS install is needed: DDS is
spoken directly (Cyclone DDS); set ROS_DOMAIN_ID / --domain as the ROS 2 system does.

DDS configuration: CYCLONEDDS_URI as usual; --loopback keeps all DDS traffic on 127.0.0.1
(lo only, no multicast), as the tests do.
"""


def add_bridge_arguments(parser: argparse.ArgumentParser) -> None:
    """The options that shape the topics (shared with `ctrlbus record --rosbag`)."""
    parser.add_argument(
        "--namespace", default="", metavar="NS", help="ROS 2 namespace of the topics (default none)"
    )
    parser.add_argument(
        "--distro",
        choices=DISTROS,
        default="jazzy",
        help="message layouts of this ROS 2 release (sensor_msgs/Range differs; default jazzy)",
    )
    parser.add_argument("--odom-frame", default="odom", metavar="F", help="odometry frame (default odom)")
    parser.add_argument(
        "--base-frame", default="base_link", metavar="F", help="robot frame (default base_link)"
    )
    parser.add_argument(
        "--rates",
        default="",
        metavar="NAME=HZ,...",
        help="publishing rates: odom (and tf, default 20), range (10), bumper (10), battery (1), "
        "diagnostics (1)",
    )
    parser.add_argument(
        "--range",
        action="append",
        default=[],
        metavar="SLOT=KIND:FOV:MIN:MAX",
        help="a distance sensor's kind (sonar or ir), field of view (degrees) and limits (m), which the "
        "base's configuration does not carry; default for all: sonar:30:0.02:2.5",
    )


def register(subparsers: Any) -> None:
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "ros2",
        help="bridge a base to ROS 2 topics over DDS (needs the ros2 extra)",
        description=DESCRIPTION,
        formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    add_port_argument(parser)
    add_baud_argument(parser)
    parser.add_argument(
        "--domain",
        default=None,
        metavar="N",
        help="DDS domain (default $ROS_DOMAIN_ID, else 0)",
    )
    add_bridge_arguments(parser)
    parser.add_argument("--stamped", action="store_true", help="cmd_vel is geometry_msgs/TwistStamped")
    parser.add_argument(
        "--cmd-vel-timeout",
        default="0.5",
        metavar="S",
        help="stop the wheels when no cmd_vel came for S seconds (default 0.5)",
    )
    parser.add_argument(
        "--core-rates",
        default="",
        metavar="NAME=HZ,...",
        help="the Core's polling rates (as ctrlbus core --rates)",
    )
    parser.add_argument(
        "--profile",
        choices=[profile.value for profile in Profile],
        default=Profile.REFERENCE.value,
        help="requests in standard frames (reference, default) or long frames (sdk2020)",
    )
    parser.add_argument(
        "--rosbag", default=None, metavar="DIR", help="also record the topics as a rosbag2 (MCAP)"
    )
    parser.add_argument(
        "--loopback",
        action="store_true",
        help="keep DDS on the loopback interface (lo, no multicast, peer 127.0.0.1; CYCLONEDDS_URI unread)",
    )
    parser.add_argument(
        "--dds-trace", default=None, metavar="FILE", help="write Cyclone DDS's discovery trace to FILE"
    )
    parser.add_argument(
        "--connect-timeout",
        default=str(DEFAULT_CONNECT_TIMEOUT_S),
        metavar="S",
        help=f"exit 2 if the base has not answered within S seconds (default "
        f"{DEFAULT_CONNECT_TIMEOUT_S:g}; 0 waits forever)",
    )
    parser.add_argument(
        "--duration", default="0", metavar="S", help="stop after S seconds (default 0: until Ctrl-C)"
    )
    parser.set_defaults(func=run)


def domain_from(value: str | None) -> int:
    text = value if value is not None else os.environ.get("ROS_DOMAIN_ID", "0") or "0"
    try:
        return check_domain(int(text))
    except ValueError:
        raise UsageError(f"the DDS domain wants a whole number 0..232, got {text!r}") from None


def refuse_existing_bag(path: str | None) -> None:
    """A rosbag2 is a new directory: refuse one that exists before anything is opened."""
    if path is not None and os.path.lexists(path):
        raise UsageError(f"--rosbag {path}: it exists already (a rosbag2 is written into a new directory)")


def maker_from_args(args: argparse.Namespace) -> Any:
    """The MessageMaker of the topic options (needs the extra)."""
    from ctrlbus.ros2.topics import MessageMaker, RangeSpec

    ranges = dict(RangeSpec.parse(text) for text in args.range)
    return MessageMaker(
        odom_frame=args.odom_frame, base_frame=args.base_frame, distro=args.distro, ranges=ranges
    )


def run(args: argparse.Namespace, stop: threading.Event | None = None) -> int:
    require_cyclonedds()
    from ctrlbus.ros2.bridge import BridgeOptions, Ros2Bridge
    from ctrlbus.ros2.dds import dds_topic_name
    from ctrlbus.ros2.pump import Rates
    from ctrlbus.ros2.rosbag import RosbagSink

    domain = domain_from(args.domain)
    timeout = positive_number("--cmd-vel-timeout", args.cmd_vel_timeout)
    connect_timeout = positive_number("--connect-timeout", args.connect_timeout, allow_zero=True)
    duration = positive_number("--duration", args.duration, allow_zero=True)
    dds_topic_name("x", args.namespace)  # a bad namespace is refused before anything opens
    refuse_existing_bag(args.rosbag)
    options = BridgeOptions(
        namespace=args.namespace,
        distro=args.distro,
        stamped=args.stamped,
        cmd_vel_timeout_s=timeout,
        rates=Rates.parse(args.rates),
        maker=maker_from_args(args),
    )
    config = CoreConfig(
        rates=PollRates.parse(args.core_rates),
        byte_time_s=byte_time_for_baud(args.baud),
        long_frames=args.profile == Profile.SDK2020,
    )

    def reopen() -> Link:
        return open_link(args.port, args.baud)

    link = reopen()
    session = CoreSession(config, port=args.port)
    runner = CoreRunner(session, link, reopen=reopen)
    bag = RosbagSink(args.rosbag, distro=args.distro) if args.rosbag else None
    bridge = Ros2Bridge(
        runner,
        options,
        domain_id=domain,
        dds_config=dds_config(
            loopback=args.loopback, trace=args.dds_trace, environment_uri=os.environ.get("CYCLONEDDS_URI")
        ),
        extra_sinks=[] if bag is None else [bag],
    )
    stop = stop if stop is not None else threading.Event()
    started = time.monotonic()
    try:
        with stop_on_signals(stop):
            runner.start()
            bridge.start()
            ns = "/" + args.namespace.strip("/") if args.namespace.strip("/") else "/"
            print(
                f"ctrlbus ros2: bridging {args.port} on DDS domain {domain}, namespace {ns}, {args.distro} "
                f"messages{' (loopback only)' if args.loopback else ''}",
                flush=True,
            )
            while not stop.wait(0.1):
                if runner.failure is not None or bridge.failure is not None:
                    print(
                        f"ctrlbus ros2: failed: {runner.failure or bridge.failure}",
                        file=sys.stderr,
                        flush=True,
                    )
                    return 1
                elapsed = time.monotonic() - started
                with runner.lock:
                    connects = session.connects
                if connect_timeout and elapsed > connect_timeout and connects == 0:
                    raise ProtocolTimeout(
                        f"no answer to CONNECT_BASE from {args.port} within {connect_timeout:g} s "
                        "(--connect-timeout 0 waits forever)"
                    )
                if duration and elapsed >= duration:
                    break
    finally:
        bridge.stop()
        runner.stop()
        if bag is not None:
            bag.close()
    counters = bridge.counters
    dropped = counters.cmd_vel_dropped_nonfinite + counters.cmd_vel_dropped_absurd
    print(
        f"ctrlbus ros2: stopped; {bridge.pump.published} messages published, cmd_vel received "
        f"{counters.cmd_vel_received}, dropped {dropped}, "
        f"watchdog stops {counters.watchdog_stops}",
        file=sys.stderr,
        flush=True,
    )
    return 0
