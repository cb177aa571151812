"""Argument types and checks shared by the commands: numbers with limits, ``--params``,
figure files."""

from __future__ import annotations

import argparse
import math
import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import Any

from gracenav.errors import OutputError

__all__ = [
    "add_palette_argument",
    "add_params_argument",
    "check_figure_path",
    "check_plant",
    "load_params",
    "number",
    "save_figure",
    "supported_figure_formats",
]


def number(
    *,
    minimum: float | None = None,
    maximum: float | None = None,
    positive: bool = False,
    integer: bool = False,
    unit: str = "",
) -> Callable[[str], float]:
    """An argparse type: a finite number (or integer) within the given limits.

    The limits are worded as in document errors (:func:`gracenav._util.validate.number_range`):
    ``expected a number in (0, 600] s, got '1e9'``.
    """
    from gracenav._util.validate import in_range, number_range

    def parse(text: str) -> float:
        try:
            value = float(int(text)) if integer else float(text)
        except (ValueError, OverflowError):
            kind = "an integer" if integer else "a number"
            raise argparse.ArgumentTypeError(f"expected {kind}, got {text!r}") from None
        if not math.isfinite(value):
            raise argparse.ArgumentTypeError(f"expected a finite number, got {text!r}")
        if not in_range(value, minimum=minimum, maximum=maximum, positive=positive):
            desc = number_range(
                minimum=minimum, maximum=maximum, positive=positive, integer=integer, unit=unit
            )
            raise argparse.ArgumentTypeError(f"expected {desc}, got {text!r}")
        return int(value) if integer else value

    parse.__name__ = "integer" if integer else "number"
    return parse


def add_palette_argument(parser: argparse.ArgumentParser, flag: str = "--palette") -> None:
    """Add ``--palette FILE`` (or ``flag``): a palette file, or a shipped palette by
    name, instead of the default."""
    parser.add_argument(
        flag,
        type=str,
        default=None,
        metavar="FILE",
        help=(
            "motion policy palette to use: a file (e.g. one written by `gracenav palette "
            "build --out FILE`) or a shipped palette by name: 'default' (0.5 m/s), "
            "'speed' (cruise levels 0.5, 1.0 and 1.2 m/s), 'smooth' (0.5 m/s, the "
            "ball's jerk within 2 m/s³), 'calm' (0.4 m/s, the ball's jerk within "
            "1.15 m/s³) or 'gentle' (0.5 m/s, the ball's jerk within 3 m/s³); a file "
            "of such a name is "
            "./NAME (default: $GRACENAV_PALETTE, else the default palette)"
        ),
    )


def add_params_argument(parser: argparse.ArgumentParser, what: str | None = None) -> None:
    """Add ``--params FILE`` (robot parameters overriding the CMU ballbot's); ``what``
    says what they are used for (default: the simulated plant only)."""
    used = (
        what
        if what is not None
        else "the simulated plant; the controllers keep their nominal design"
    )
    parser.add_argument(
        "--params",
        type=Path,
        default=None,
        metavar="FILE",
        help=(
            "YAML or JSON file of robot parameters (BallbotParams field names, SI units) "
            "for " + used + "; fields not given keep the CMU ballbot's values, e.g. a file "
            "with only 'body_mass: 60'"
        ),
    )


def load_params(args: argparse.Namespace) -> Any:
    """The plant parameters of ``--params`` (None when not given)."""
    from gracenav.params import BallbotParams

    path = getattr(args, "params", None)
    return None if path is None else BallbotParams.load_overrides(path)


def check_plant(plant: str, where: str = "--plant") -> None:
    """Refuse the MuJoCo plant up front when its optional dependency is missing."""
    import importlib.util

    from gracenav.errors import ConfigError

    if plant == "mujoco" and importlib.util.find_spec("mujoco") is None:
        raise ConfigError(
            f"{where} mujoco needs the optional dependency mujoco: "
            "pip install 'gracenav[mujoco]', or use the model3d plant"
        )


def supported_figure_formats() -> dict[str, str]:
    """Figure file suffixes matplotlib can write (without the dot) and their names."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    formats: dict[str, str] = FigureCanvasAgg(Figure()).get_supported_filetypes()
    return formats


def check_figure_path(path: Path, flag: str = "--out") -> Path:
    """Check a figure output file up front: a supported suffix, not a directory, a folder
    that is a directory (or can be created).

    Raises
    ------
    OutputError
    """
    if path.is_dir():
        raise OutputError(f"{flag} {path} is a directory; give a file name such as fig.png")
    suffix = path.suffix.lower().lstrip(".")
    formats = supported_figure_formats()
    if suffix not in formats:
        got = f"'.{suffix}'" if suffix else "no suffix"
        raise OutputError(
            f"{flag} {path}: {got} is not a figure format; use one of "
            f"{', '.join('.' + f for f in sorted(formats))}"
        )
    for parent in path.absolute().parents:
        if parent.exists():
            if not parent.is_dir():
                raise OutputError(f"{flag} {path}: {parent} is a file, not a directory")
            if not os.access(parent, os.W_OK | os.X_OK) and parent == path.absolute().parent:
                raise OutputError(f"{flag} {path}: cannot write in {parent} (permission denied)")
            break
    return path


def save_figure(path: Path, draw: Callable[[Path], Any], flag: str = "--out") -> Path:
    """Call ``draw(tmp)`` to write the figure to a temporary file beside ``path`` (same
    suffix), then rename it to ``path``: a failed or interrupted run leaves no partial
    file. Returns ``path``."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(prefix=f".{path.stem}.tmp-", suffix=path.suffix, dir=path.parent)
        os.close(fd)
    except OSError as exc:
        raise OutputError(f"{flag} {path}: cannot write beside it: {exc.strerror}") from None
    try:
        draw(Path(tmp))
        umask = os.umask(0)
        os.umask(umask)
        os.chmod(tmp, 0o666 & ~umask)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path
