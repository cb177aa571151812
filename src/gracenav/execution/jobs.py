"""Computations longer than a control tick, run in the background of the hybrid
controller (:attr:`gracenav.execution.ExecutionOptions.planning`)."""

from __future__ import annotations

import math
import time as _time
from collections.abc import Callable
from concurrent.futures import Executor, Future
from typing import Any

__all__ = ["Job"]


class Job:
    """A computation longer than a tick (:attr:`ExecutionOptions.planning`).

    ``"threaded"``: submitted to ``executor``, ready when done. ``"modelled"``: run at
    once, ready ``latency`` (s; None: its wall time) after tick ``tick``.
    """

    def __init__(
        self,
        fn: Callable[[], Any],
        *,
        executor: Executor | None,
        tick: int,
        dt: float,
        latency: float | None,
    ) -> None:
        self.future: Future[Any] | None = None
        self.value: Any = None
        self.due = tick
        if executor is not None:
            self.future = executor.submit(fn)
        else:
            t0 = _time.perf_counter()
            self.value = fn()
            lat = _time.perf_counter() - t0 if latency is None else latency
            self.due = tick + max(1, math.ceil(lat / dt - 1e-9))

    def ready(self, tick: int) -> bool:
        """Whether its result may be used at tick ``tick``."""
        if self.future is not None:
            return self.future.done()
        return tick >= self.due

    def result(self) -> Any:
        """Its result (waits for a thread that has not finished; raises its error)."""
        return self.future.result() if self.future is not None else self.value
