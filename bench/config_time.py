# SPDX-License-Identifier: MIT
"""Time to configured on a noisy line: the Core emulator connecting to a base through the fault
injector, in virtual time (docs/reliability.md, "Getting the configuration on a noisy line").

For each bit error rate and seed, a fresh `CoreSession` and Python simulated base
(`ctrlbus.vtime`, 115200 baud 8N1, `ber=...` on both directions) run for `--seconds` of virtual
time. Measured: the time from the Core's first CONNECT_BASE to its first "connected" (configured,
SYSTEM_UP_OK answered, polling), the disconnects counted until then and over the whole run (the
later ones are polling's: three silent attempts in a row), lost requests, and
which configuration the Core uses at the end (the blob arrives later on a harsh line).

Two blobs: the reference firmware's own (308 bytes, a 313-byte answer: its recorded answer in
python/tests/data/refbase_answers.json) and the one the simulated base makes from its description
by default (458 bytes, every sensor listed).

    .venv/bin/python bench/config_time.py                        # JSON on stdout; deterministic
    .venv/bin/python bench/config_time.py --bers 1e-3 --seeds 5  # a smaller run
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from collections.abc import Sequence
from typing import Any

from common import REPO, ensure_ctrlbus_importable

ensure_ctrlbus_importable()

from ctrlbus.base import BaseConfig, BaseStack  # noqa: E402  (after the path is set up)
from ctrlbus.core import CoreSession  # noqa: E402
from ctrlbus.core.session import ConnectionState  # noqa: E402
from ctrlbus.faults import FaultFilter, fault_models  # noqa: E402
from ctrlbus.frame import StreamDecoder  # noqa: E402
from ctrlbus.sim.base import SimulatedBase  # noqa: E402
from ctrlbus.sim.blob import blob_from_description  # noqa: E402
from ctrlbus.sim.world import World  # noqa: E402
from ctrlbus.vtime import VirtualBus  # noqa: E402

RECORDED = REPO / "python" / "tests" / "data" / "refbase_answers.json"


def reference_blob() -> bytes:
    raw = bytes.fromhex(json.loads(RECORDED.read_text())["answers"]["GET_BASE_CONF_ADV"])
    (frame,) = StreamDecoder().feed(raw)
    return frame.payload


def one_run(blob: bytes, ber: float, seed: int, seconds: float) -> dict[str, Any]:
    stack = BaseStack(SimulatedBase(World(seed=1), binary_config=blob), BaseConfig())
    core = CoreSession(port="fault")
    to_base, to_core = fault_models(f"ber={ber:g}", seed=seed)
    bus = VirtualBus(core, stack, to_base=FaultFilter(to_base), to_core=FaultFilter(to_core))
    configured = bus.run_until(lambda: core.state is ConnectionState.CONNECTED, seconds, 0.01)
    at = round(bus.now, 3) if configured else None
    while_configuring = core.link_stats()["disconnects"]
    bus.run_for(max(0.0, seconds - bus.now))
    stats = core.link_stats()
    return {
        "seed": seed,
        "configured_s": at,
        "disconnects_configuring": while_configuring,
        "disconnects": stats["disconnects"],
        "lost_requests": stats["lost_requests"],
        "config_source": core.telemetry.config_source,
        "blob": core.telemetry.blob_status,
    }


def summary(runs: list[dict[str, Any]]) -> dict[str, Any]:
    times = sorted(run["configured_s"] for run in runs if run["configured_s"] is not None)
    return {
        "runs": len(runs),
        "configured": len(times),
        "median_s": round(statistics.median(times), 3) if times else None,
        "p90_s": round(times[max(0, round(0.9 * len(times)) - 1)], 3) if times else None,
        "max_s": times[-1] if times else None,
        "disconnects_configuring": sum(run["disconnects_configuring"] for run in runs),
        "disconnects": sum(run["disconnects"] for run in runs),
        "lost_requests": sum(run["lost_requests"] for run in runs),
        "blob_in_use_at_end": sum(run["blob"] == "used" for run in runs),
    }


def main(argv: Sequence[str] | None = None) -> int:
    formatter = argparse.RawDescriptionHelpFormatter
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=formatter)
    parser.add_argument("--bers", default="1e-4,1e-3", help="bit error rates, comma-separated")
    parser.add_argument("--seeds", type=int, default=20, help="seeds 1..N per rate (default 20)")
    parser.add_argument("--seconds", type=float, default=60.0, help="virtual seconds per run (default 60)")
    args = parser.parse_args(argv)
    blobs = {
        "reference blob": reference_blob(),
        "simulated base's default blob": blob_from_description(World(seed=1).base),
    }
    results: dict[str, Any] = {"seconds": args.seconds, "seeds": args.seeds, "cases": []}
    for label, blob in blobs.items():
        for text in args.bers.split(","):
            ber = float(text)
            runs = [one_run(blob, ber, seed, args.seconds) for seed in range(1, args.seeds + 1)]
            case = {"blob": label, "ber": ber, "blob_bytes": len(blob), **summary(runs), "each": runs}
            results["cases"].append(case)
            print(
                f"{label}, ber {ber:g}: median {case['median_s']} s, p90 {case['p90_s']} s, "
                f"max {case['max_s']} s, disconnects while configuring {case['disconnects_configuring']}, "
                f"in the whole run {case['disconnects']}, "
                f"blob in use after {args.seconds:g} s: {case['blob_in_use_at_end']}/{len(runs)}",
                file=sys.stderr,
            )
    json.dump(results, sys.stdout, indent=1)
    print()
    return 0


if __name__ == "__main__":
    sys.exit(main())
