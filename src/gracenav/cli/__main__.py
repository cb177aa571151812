"""``python -m gracenav.cli``."""

from __future__ import annotations

from gracenav.cli import entry

entry()
