# SPDX-License-Identifier: MIT
"""`ctrlbus record --rosbag DIR`: the ROS 2 bridge's topics written as a rosbag2 (MCAP, CDR), from a
live base or converted from a capture (docs/ros2.md).

    ctrlbus record --rosbag DIR --port URL [--duration S] [topic options as ctrlbus ros2]
    ctrlbus record --rosbag DIR --capture FILE [topic options]

Live, it runs the Core emulator against the base (as `ctrlbus core`) and writes the topics at their
rates; no DDS participant is made. From a capture (`ctrlbus capture`, pcap) it reads both
directions as `ctrlbus decode` does and writes the topics at the capture's times. Needs the ros2
extra; DIR must not exist yet.
"""

from __future__ import annotations

import argparse
import sys
import threading
import time
from functools import partial
from typing import Any

from ctrlbus.cli.common import add_baud_argument, positive_number, stop_on_signals
from ctrlbus.cli.ros2_cmd import add_bridge_arguments, maker_from_args, refuse_existing_bag
from ctrlbus.core import CoreConfig, CoreRunner, CoreSession, byte_time_for_baud
from ctrlbus.errors import ProtocolTimeout
from ctrlbus.link import Link
from ctrlbus.ports import open_link
from ctrlbus.ros2.dds import require_cyclonedds

__all__ = ["register", "run"]

DEFAULT_CONNECT_TIMEOUT_S = 5.0


def register(subparsers: Any) -> None:
    parser: argparse.ArgumentParser = subparsers.add_parser(
        "record",
        help="write the ROS 2 topics of a base (live or from a capture) as a rosbag2 (needs the ros2 extra)",
        description=__doc__.split("\n\n", 1)[0].split(": ", 1)[1] if __doc__ else None,
    )
    parser.add_argument("--rosbag", required=True, metavar="DIR", help="the rosbag2 directory to create")
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--port", metavar="URL", help="a live base (pyserial URL, as ctrlbus core)")
    source.add_argument("--capture", metavar="FILE", help="a capture of a Core and a base (pcap)")
    add_baud_argument(parser)
    add_bridge_arguments(parser)
    parser.add_argument(
        "--duration", default="0", metavar="S", help="live: stop after S seconds (default: Ctrl-C)"
    )
    parser.add_argument(
        "--connect-timeout",
        default=str(DEFAULT_CONNECT_TIMEOUT_S),
        metavar="S",
        help="live: exit 2 if the base has not answered within S seconds (0 waits forever)",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace, stop: threading.Event | None = None) -> int:
    require_cyclonedds("ctrlbus record --rosbag")
    from ctrlbus.ros2.pump import Rates, TopicPump
    from ctrlbus.ros2.rosbag import RosbagSink
    from ctrlbus.ros2.topics import BridgeCounters

    rates = Rates.parse(args.rates)
    maker = maker_from_args(args)
    duration = positive_number("--duration", args.duration, allow_zero=True)
    connect_timeout = positive_number("--connect-timeout", args.connect_timeout, allow_zero=True)
    counters = BridgeCounters()
    refuse_existing_bag(args.rosbag)
    if args.capture is not None:
        from ctrlbus.ros2.capture import CaptureModel, capture_moments

        model = CaptureModel()
        with RosbagSink(args.rosbag, distro=args.distro) as bag:
            pump = TopicPump(maker, rates, [bag], namespace=args.namespace)
            for moment in capture_moments(args.capture, model):
                pump.run(moment, partial(model.state, moment), counters)
        print(
            f"ctrlbus record: {bag.messages} messages from {args.capture} in {args.rosbag}", file=sys.stderr
        )
        return 0

    from ctrlbus.ros2.bridge import session_state

    def reopen() -> Link:
        return open_link(args.port, args.baud)

    link = reopen()
    session = CoreSession(CoreConfig(byte_time_s=byte_time_for_baud(args.baud)), port=args.port)
    runner = CoreRunner(session, link, reopen=reopen)
    stop = stop if stop is not None else threading.Event()
    started = time.monotonic()

    def read_state() -> Any:
        with runner.lock:
            return session_state(session, time.time())

    with RosbagSink(args.rosbag, distro=args.distro) as bag:
        pump = TopicPump(maker, rates, [bag], namespace=args.namespace)
        try:
            with stop_on_signals(stop):
                runner.start()
                print(f"ctrlbus record: recording {args.port} into {args.rosbag}", flush=True)
                while True:
                    now = time.monotonic()
                    elapsed = now - started
                    with runner.lock:
                        connects = session.connects
                    if connect_timeout and elapsed > connect_timeout and connects == 0:
                        raise ProtocolTimeout(
                            f"no answer to CONNECT_BASE from {args.port} within {connect_timeout:g} s"
                        )
                    if duration and elapsed >= duration:
                        break
                    if runner.failure is not None:
                        print(f"ctrlbus record: the Core failed: {runner.failure}", file=sys.stderr)
                        return 1
                    if connects:
                        pump.run(now, read_state, counters)
                    if stop.wait(max(0.0, min(0.1, pump.next_due(now) - time.monotonic()))):
                        break
        finally:
            runner.stop()
    print(f"ctrlbus record: {bag.messages} messages in {args.rosbag}", file=sys.stderr)
    return 0
