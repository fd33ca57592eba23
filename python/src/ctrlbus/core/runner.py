# SPDX-License-Identifier: MIT
"""Run a CoreSession in real time: a thread that owns the link and passes time.monotonic().

The thread writes what `poll()` returns, reads the link with a short timeout and hands the bytes to
`receive()`. A failing link is not a crash: the session sees it as a lost connection, and the
runner reopens the link (if it was given a way to) and carries on. `stop()` asks the session to
stop on purpose (it sends SEND_EVENT CORE_DISCONNECT if the base is connected), waits a moment for
that, then closes the link.

The session is sans-IO and holds no lock; the runner owns the thread that drives it, so the runner
holds the lock: `lock` is taken around each call the thread makes (never while it waits for the
link), and any other thread that reads or commands the session takes it too:

    with runner.lock:
        runner.session.set_velocity(0.2, 0.0)
        pose = runner.session.pose
"""

from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections.abc import Callable

from ctrlbus.core.session import CoreSession
from ctrlbus.errors import CtrlbusError, LinkError
from ctrlbus.link import Link

__all__ = [
    "READ_TIMEOUT_S",
    "REOPEN_INTERVAL_S",
    "STOP_GRACE_S",
    "CoreRunner",
]

log = logging.getLogger("ctrlbus.core")

READ_TIMEOUT_S = 0.02  # longest wait in one read: bounds how late poll() and stop() are seen
REOPEN_INTERVAL_S = 1.0
STOP_GRACE_S = 1.0  # time allowed for the CORE_DISCONNECT exchange when stopping


class CoreRunner:
    """Drive `session` over `link` from a thread; `reopen` (optional) makes a new link after a
    failure."""

    def __init__(
        self,
        session: CoreSession,
        link: Link,
        *,
        reopen: Callable[[], Link] | None = None,
        read_timeout_s: float = READ_TIMEOUT_S,
        reopen_interval_s: float = REOPEN_INTERVAL_S,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.session = session
        self.lock = threading.RLock()  # held around every use of the session (see the module)
        self._link: Link | None = link
        self._reopen = reopen
        self._read_timeout_s = read_timeout_s
        self._reopen_interval_s = reopen_interval_s
        self._clock = clock
        self._stop = threading.Event()
        self._stop_grace_s = STOP_GRACE_S
        self._thread: threading.Thread | None = None
        self.failure: str | None = None  # an unexpected error that ended the thread
        self.link_errors = 0

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def start(self) -> None:
        if self._thread is not None:
            raise CtrlbusError("the Core runner is already started")
        self._thread = threading.Thread(target=self._run, name="ctrlbus-core", daemon=True)
        self._thread.start()

    def stop(self, timeout_s: float = STOP_GRACE_S + 1.0) -> None:
        """Stop the session on purpose, close the link and end the thread; idempotent."""
        self._stop_grace_s = max(0.0, min(STOP_GRACE_S, timeout_s))
        self._stop.set()
        thread = self._thread
        if thread is not None:
            thread.join(timeout_s)
            if thread.is_alive():
                log.warning("the Core runner did not stop within %.1f s", timeout_s)
        else:
            self._close()

    def __enter__(self) -> CoreRunner:
        self.start()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self.stop()

    def _run(self) -> None:
        session = self.session
        stop_deadline: float | None = None
        failed_at: float | None = None
        try:
            while True:
                if self._stop.is_set() and stop_deadline is None:
                    with self.lock:
                        session.request_stop()
                    stop_deadline = self._clock() + self._stop_grace_s
                if stop_deadline is not None:
                    with self.lock:
                        stopped = session.stopped
                    if stopped or self._clock() > stop_deadline:
                        break
                link = self._link
                if link is None:
                    failed_at = self._try_reopen(failed_at)
                    continue
                try:
                    self._exchange(link)
                except LinkError as exc:
                    self.link_errors += 1
                    with self.lock:
                        session.link_failed(str(exc), self._clock())
                    self._close()
                    failed_at = self._clock()
        except Exception as exc:  # a bug: report it rather than die silently
            self.failure = f"{type(exc).__name__}: {exc}"
            log.exception("the Core runner failed")
        finally:
            self._close()

    def _exchange(self, link: Link) -> None:
        session = self.session
        with self.lock:
            frame = session.poll(self._clock())
        if frame is not None:
            link.write(frame)
        with self.lock:
            wake = session.next_poll_time()
        timeout = self._read_timeout_s
        if wake is not None:
            timeout = max(0.0, min(timeout, wake - self._clock()))
        data = link.read(timeout)
        if data:
            with self.lock:
                session.receive(data, self._clock())

    def _try_reopen(self, failed_at: float | None) -> float | None:
        """Wait for the next reopen attempt (or the stop), then try; returns the failure time."""
        if self._reopen is None:
            self._stop.wait(self._read_timeout_s)
            return failed_at
        now = self._clock()
        if failed_at is not None and now - failed_at < self._reopen_interval_s:
            self._stop.wait(min(self._read_timeout_s * 5, self._reopen_interval_s - (now - failed_at)))
            return failed_at
        try:
            self._link = self._reopen()
        except CtrlbusError as exc:
            with self.lock:
                self.session.link_failed(str(exc), self._clock())
            return self._clock()
        return None

    def _close(self) -> None:
        link, self._link = self._link, None
        if link is not None:
            with contextlib.suppress(Exception):
                link.close()
