"""A minimal progress bar on standard error (no dependency)."""

from __future__ import annotations

import sys
import time
from types import TracebackType
from typing import TextIO

__all__ = ["Progress"]


class Progress:
    """Progress bar ``label [#####.....] k/n  elapsed``; silent when ``enabled`` is False
    or the stream is not a terminal and ``force`` is False."""

    def __init__(
        self,
        total: int,
        label: str,
        *,
        enabled: bool = True,
        stream: TextIO | None = None,
        force: bool = False,
    ) -> None:
        self.total = max(int(total), 1)
        self.label = label
        self.count = 0
        self.stream = stream if stream is not None else sys.stderr
        self.enabled = enabled and (force or self.stream.isatty())
        self.start = time.perf_counter()
        self._last = 0.0

    def update(self, n: int = 1) -> None:
        """Advance by ``n`` steps and redraw (at most 10 times per second)."""
        self.count = min(self.count + n, self.total)
        now = time.perf_counter()
        if self.enabled and (now - self._last > 0.1 or self.count == self.total):
            self._last = now
            frac = self.count / self.total
            bar = "#" * int(30 * frac) + "." * (30 - int(30 * frac))
            self.stream.write(
                f"\r{self.label} [{bar}] {self.count}/{self.total} {now - self.start:6.1f} s"
            )
            self.stream.flush()

    def __enter__(self) -> Progress:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        if self.enabled:
            self.stream.write("\n")
            self.stream.flush()
