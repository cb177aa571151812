"""The public API: every name in gracenav.__all__ resolves; nothing else does."""

from __future__ import annotations

import pytest

import gracenav


def test_every_public_name_resolves() -> None:
    for name in gracenav.__all__:
        assert getattr(gracenav, name) is not None
    assert set(gracenav.__all__) <= set(dir(gracenav))


def test_unknown_name() -> None:
    with pytest.raises(AttributeError, match="no attribute 'teleport'"):
        gracenav.teleport  # noqa: B018


def test_examples_run_headless(capsys) -> None:
    import runpy
    from pathlib import Path

    script = Path(__file__).resolve().parents[1] / "examples" / "navigate.py"
    runpy.run_path(str(script), run_name="__main__")
    assert "goal_reached" in capsys.readouterr().out
