# SPDX-License-Identifier: MIT
"""Link statistics of a Core session: request rate, answer latency, errors, retries.

Times are the ones the session is given (never a clock read here). Latency is measured from the
moment a request is handed to the link (the `poll` that returned it) to the moment its answer is
complete (the `receive` that completed it), so it includes both frames' time on the wire.
"""

from __future__ import annotations

import math
from collections import Counter, deque
from dataclasses import dataclass, field

from ctrlbus.constants import LINE_FAULT_BIT_NAMES

__all__ = [
    "LATENCY_SAMPLES",
    "RATE_WINDOW_S",
    "LinkStats",
    "percentile",
]

RATE_WINDOW_S = 5.0  # requests_per_s counts the requests of the last few seconds
LATENCY_SAMPLES = 500  # percentiles over the last few hundred answers


def percentile(sorted_values: list[float], fraction: float) -> float:
    """Nearest-rank percentile of an ascending, non-empty list (fraction in 0..1)."""
    rank = max(1, min(len(sorted_values), math.ceil(fraction * len(sorted_values))))
    return sorted_values[rank - 1]


@dataclass
class LinkStats:
    """Counters of one Core session (all of them survive reconnects)."""

    requests: int = 0  # frames sent, retries and flushing SYNCs included
    answers: int = 0  # answers matched to a request
    retries: int = 0  # requests sent again after a timeout or a transport error
    timeouts: int = 0  # attempts that got no complete answer in time
    errors_by_code: Counter[int] = field(default_factory=Counter)
    invalid_answers: int = 0  # INVALID (0xFF) answers
    malformed_answers: int = 0  # answers whose payload does not fit the request (a codec error)
    stray_answers: int = 0  # frames that arrived while no request was outstanding
    not_synced_reports: int = 0  # ERROR 0x0010: bytes between frames reached the base
    flushed_frames: int = 0  # frames discarded after a flushing SYNC
    damaged_config_answers: int = 0  # configuration reads answered, but nothing intact arrived
    unsupported_conf_adv: int = 0  # ERROR 0x8000 to GET_BASE_CONF_ADV: no blob (not counted as an error)
    watchdog_trips: int = 0  # gaps > watchdog_s without a CTRL_BUS request to a connected base
    watchdog_reported: int = 0  # times the base's health list newly showed 0x01038000
    connect_attempts: int = 0  # CONNECT_BASE requests (unanswered ones are not counted as timeouts)
    connects: int = 0  # successful CONNECT_BASE answers
    disconnects: int = 0  # connections lost (a request failed every attempt)
    # The fate of each request that matters (configuration, SYSTEM_UP, polling; §11.6):
    tracked_requests: int = 0  # such requests started (first attempts)
    answered_requests: int = 0  # answered (OK, or an ERROR that is an answer)
    superseded: int = 0  # periodic ones that failed and were replaced by their next period
    abandoned_at_disconnect: int = 0  # in flight when the base was declared disconnected
    lost_requests: int = 0  # given up while the base still counted as connected (should stay 0)
    line_fault_bits: Counter[int] = field(default_factory=Counter)  # line-fault ERRORs by bit
    _send_times: deque[float] = field(default_factory=deque)
    _latencies: deque[float] = field(default_factory=lambda: deque(maxlen=LATENCY_SAMPLES))

    def count_request(self, now: float) -> None:
        self.requests += 1
        self._send_times.append(now)
        self._trim(now)

    def count_line_fault(self, code: int) -> None:
        """An ERROR code below 0x0100: count each of its bits (0x10, 0x20, 0x40, 0x80)."""
        for bit in LINE_FAULT_BIT_NAMES:
            if code & bit:
                self.line_fault_bits[bit] += 1

    def count_answer(self, latency_s: float) -> None:
        self.answers += 1
        self._latencies.append(latency_s)

    def _trim(self, now: float) -> None:
        times = self._send_times
        while times and times[0] < now - RATE_WINDOW_S:
            times.popleft()

    def requests_per_s(self, now: float, since: float) -> float:
        """Requests per second over the last RATE_WINDOW_S (or since `since`, if that is later)."""
        self._trim(now)
        span = min(RATE_WINDOW_S, now - since)
        if span <= 0:
            return 0.0
        return sum(1 for t in self._send_times if t > now - span) / span

    def latency_percentiles_ms(self) -> tuple[float | None, float | None]:
        """(p50, p99) in milliseconds over the recent answers; (None, None) before any."""
        if not self._latencies:
            return None, None
        ordered = sorted(self._latencies)
        return percentile(ordered, 0.50) * 1000.0, percentile(ordered, 0.99) * 1000.0

    @property
    def latency_samples(self) -> int:
        return len(self._latencies)
