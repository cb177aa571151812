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
