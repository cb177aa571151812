"""Progress bars on standard error, on their own line (tqdm).

A bar is drawn only when its stream is a terminal (or ``force``), and it is erased when
it closes, so the messages printed after it (results, ``gracenav: error: ...``) start
on a clean line; :meth:`Progress.write` prints a message while it is shown.
"""

from __future__ import annotations

import sys
from types import TracebackType
from typing import TextIO

from tqdm import tqdm

__all__ = ["Progress"]


class Progress:
    """Progress bar ``label: 40%|####      | k/n [elapsed<remaining]``.

    Parameters
    ----------
    total : int
        Number of steps (at least 1).
    label : str
        Text before the bar.
    enabled : bool
        False never draws.
    stream : file, optional
        Default: ``sys.stderr``.
    force : bool
        Draw even when ``stream`` is not a terminal.
    """

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
        isatty = getattr(self.stream, "isatty", None)
        self.enabled = bool(enabled and (force or (isatty is not None and isatty())))
        self._bar = tqdm(
            total=self.total,
            desc=label,
            file=self.stream,
            disable=not self.enabled,
            leave=False,
            dynamic_ncols=True,
            mininterval=0.1,
        )

    def update(self, n: int = 1) -> None:
        """Advance by ``n`` steps."""
        n = max(0, min(int(n), self.total - self.count))
        self.count += n
        self._bar.update(n)

    def set_label(self, label: str) -> None:
        """Change the text before the bar (e.g. the stage being run)."""
        self.label = label
        self._bar.set_description_str(label)

    def write(self, message: str) -> None:
        """Print ``message`` on its own line above the bar."""
        if self.enabled:
            self._bar.write(message, file=self.stream)
        else:
            print(message, file=self.stream, flush=True)

    def close(self) -> None:
        """Erase the bar."""
        self._bar.close()

    def __enter__(self) -> Progress:
        return self

    def __exit__(
        self,
        exc_type: type[BaseException] | None,
        exc: BaseException | None,
        tb: TracebackType | None,
    ) -> None:
        self.close()
