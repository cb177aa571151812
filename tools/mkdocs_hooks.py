"""MkDocs hooks of the documentation site (``mkdocs.yml``, ``hooks:``).

A page line ``<!-- gracenav-help -->`` becomes the help of every ``gracenav`` command
and sub-command, taken from the command line's own argument parser
(:func:`gracenav.cli.build_parser`) at build time, so the command-line reference
cannot drift from the code.
"""

from __future__ import annotations

import argparse
import os
from typing import Any

MARKER = "<!-- gracenav-help -->"
WIDTH = 88
"""Columns the help is wrapped to (argparse reads ``COLUMNS``)."""

__all__ = ["MARKER", "cli_reference", "commands", "on_page_markdown"]


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def commands(
    parser: argparse.ArgumentParser | None = None, prefix: tuple[str, ...] = ()
) -> list[tuple[tuple[str, ...], argparse.ArgumentParser]]:
    """Every command of the parser tree, depth first: ``((), gracenav)``,
    ``(("run",), run)``, ``(("palette",), palette)``, ``(("palette", "build"), ...)``."""
    if parser is None:
        from gracenav.cli import build_parser

        parser = build_parser()
    out = [(prefix, parser)]
    for name, sub in _subcommands(parser).items():
        out += commands(sub, (*prefix, name))
    return out


def cli_reference() -> str:
    """Markdown: one section per command, its ``--help`` in a code block."""
    previous = os.environ.get("COLUMNS")
    os.environ["COLUMNS"] = str(WIDTH)
    try:
        parts = []
        for path, parser in commands():
            level = "#" * min(2 + max(len(path) - 1, 0), 4)
            title = " ".join(("gracenav", *path))
            parts.append(f"{level} `{title}`\n\n```text\n{parser.format_help().rstrip()}\n```\n")
        return "\n".join(parts)
    finally:
        if previous is None:
            del os.environ["COLUMNS"]
        else:
            os.environ["COLUMNS"] = previous


def on_page_markdown(markdown: str, **kwargs: Any) -> str:
    """Expand :data:`MARKER` (MkDocs event)."""
    if MARKER not in markdown:
        return markdown
    return markdown.replace(MARKER, cli_reference())
