"""The README and the documentation pages against the code: every command line shown
parses, every file snippet is valid, the file references list exactly the keys the
parsers accept (with their units, defaults and limits), and the API and command-line
references cover the public surface. (The site itself is built with ``--strict`` by
``make docs``, a step of ``make test``.)"""

from __future__ import annotations

import argparse
import copy
import inspect
import math
import re
import runpy
import shlex
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
import yaml

from gracenav._util.validate import Fields
from gracenav.errors import GracenavError

ROOT = Path(__file__).resolve().parent.parent
DOCS = ROOT / "docs"
PAGES = [ROOT / "README.md", *sorted(DOCS.rglob("*.md"))]


def _blocks(text: str, *langs: str) -> list[str]:
    pattern = r"^```(?:" + "|".join(langs) + r")\n(.*?)^```"
    return re.findall(pattern, text, flags=re.DOTALL | re.MULTILINE)


def _command_lines(prog: str) -> Iterator[tuple[str, str]]:
    """(page, line) of every command line starting with ``prog`` in a shell block or an
    inline code span of a page; comments and a leading ``VAR=value`` are dropped."""
    for page in PAGES:
        text = page.read_text()
        lines = [ln for b in _blocks(text, "sh", "bash", "console") for ln in b.splitlines()]
        lines += re.findall(r"`([^`\n]+)`", re.sub(r"```.*?```", "", text, flags=re.DOTALL))
        for line in lines:
            line = line.split(" #")[0].strip()
            if prog not in line.split()[:3]:
                continue
            words = shlex.split(line)
            while words and re.fullmatch(r"[A-Z_]+=\S*", words[0]):
                words = words[1:]
            if words[:1] == [prog] or (prog == "python" and words[:1] == [".venv/bin/python"]):
                yield page.name, " ".join(words)


def _hooks() -> Any:
    sys.path.insert(0, str(ROOT / "tools"))
    try:
        import mkdocs_hooks
    finally:
        sys.path.remove(str(ROOT / "tools"))
    return mkdocs_hooks


def test_gracenav_command_lines_parse() -> None:
    """Each command line parses; a span naming a command (`gracenav simulate balance`)
    names one that exists."""
    from gracenav.cli import build_parser

    names = {path for path, _ in _hooks().commands()}
    seen = 0
    for page, line in _command_lines("gracenav"):
        words = shlex.split(line)[1:]
        if "..." in words or tuple(words) in names:
            continue  # a command family or a command's name in prose
        parser = build_parser()
        try:
            parser.parse_args(words)
        except SystemExit as exc:
            assert exc.code == 0, f"{page}: `{line}` does not parse"  # --help exits with 0
        seen += 1
    assert seen >= 30  # README and docs together show many


class _Captured(Exception):
    def __init__(self, parser: argparse.ArgumentParser) -> None:
        self.parser = parser


def test_script_command_lines_parse(monkeypatch: pytest.MonkeyPatch) -> None:
    """``python bench/...py --flags``: the script exists and its own argument parser
    takes the flags (captured at ``parse_args``, so nothing runs)."""
    original = argparse.ArgumentParser.parse_args
    seen = 0
    for page, line in _command_lines("python"):
        words = shlex.split(line)[1:]
        if words[:1] == ["-m"] or not words:
            continue
        script = ROOT / words[0]
        assert script.is_file(), f"{page}: `{line}`: no {words[0]}"
        args = words[1:]
        if "ArgumentParser" not in script.read_text():
            assert not args, f"{page}: `{line}`: {words[0]} takes no arguments"
            continue

        def capture(self: argparse.ArgumentParser, *a: Any, **k: Any) -> Any:
            raise _Captured(self)

        monkeypatch.setattr(argparse.ArgumentParser, "parse_args", capture)
        monkeypatch.setattr(sys, "argv", [str(script)])
        monkeypatch.syspath_prepend(str(script.parent))  # scripts import their neighbours
        with pytest.raises(_Captured) as caught:
            runpy.run_path(str(script), run_name="__main__")
        monkeypatch.setattr(argparse.ArgumentParser, "parse_args", original)
        caught.value.parser.exit = _no_exit(page, line)  # type: ignore[method-assign]
        original(caught.value.parser, args)
        seen += 1
    assert seen >= 5


def _no_exit(page: str, line: str) -> Any:
    def exit(status: int = 0, message: str | None = None) -> None:
        raise AssertionError(f"{page}: `{line}`: {message}")

    return exit


def _yaml_snippets() -> Iterator[tuple[str, dict[str, Any]]]:
    for page in PAGES:
        for block in _blocks(page.read_text(), "yaml"):
            doc = yaml.safe_load(block)  # every YAML snippet is valid YAML
            if isinstance(doc, dict):
                yield page.name, doc


def test_scenario_and_campaign_snippets_are_valid(tmp_path: Path) -> None:
    from gracenav.campaign import parse_campaign
    from gracenav.scenarios import parse_scenario
    from gracenav.world import load_map

    kinds = []
    for page, doc in _yaml_snippets():
        if "trials" in doc:
            parse_campaign(doc, source=page, base=ROOT / "examples" / "campaigns")
            kinds.append("campaign")
        elif "task" in doc:
            scenario = parse_scenario(doc, source=page, base=tmp_path)
            if isinstance(scenario.map_source, dict):
                load_map(scenario.map_source)
            kinds.append("scenario")
    assert kinds.count("scenario") >= 3 and kinds.count("campaign") >= 1


def test_python_snippets_of_the_docs_run() -> None:
    """The ``python`` blocks of each docs page, in order, in one namespace (the
    README's are run by tests/test_api.py)."""
    ran = 0
    for page in sorted(DOCS.rglob("*.md")):
        blocks = _blocks(page.read_text(), "python")
        if not blocks:
            continue
        namespace: dict[str, Any] = {"__name__": "docs_snippet"}
        exec(compile("\n".join(blocks), str(page), "exec"), namespace)
        ran += 1
    assert ran >= 1


# -- the file references against the parsers ------------------------------------------


class _Recorder:
    """Records every key a :class:`Fields` allows (``check_keys``) and the limits of
    every value it reads, by key path with list indices dropped (``x[3].y`` → ``x[].y``)."""

    def __init__(self, monkeypatch: pytest.MonkeyPatch) -> None:
        self.allowed: set[str] = set()
        self.specs: dict[str, dict[str, Any]] = {}
        self.prefix = ""
        rec = self
        check_keys = Fields.check_keys

        def record_keys(self: Fields, allowed: Any) -> None:
            for k in allowed:
                rec.allowed.add(rec.norm(self.path(k)))
            check_keys(self, allowed)

        monkeypatch.setattr(Fields, "check_keys", record_keys)
        for method in ("number", "integer", "choice", "boolean", "vector", "points", "items"):
            monkeypatch.setattr(Fields, method, self._wrap(getattr(Fields, method)))

    def norm(self, path: str) -> str:
        return self.prefix + re.sub(r"\[\d+\]", "[]", path)

    def _wrap(self, fn: Any) -> Any:
        rec = self

        signature = inspect.signature(fn)

        def wrapped(self: Fields, key: str, *args: Any, **kwargs: Any) -> Any:
            if not key.endswith("]"):  # an item of points() is checked as its list
                bound = signature.bind(self, key, *args, **kwargs)
                bound.apply_defaults()
                spec = dict(bound.arguments)
                spec.update(spec.pop("kwargs", {}))
                spec["kind"] = fn.__name__
                rec.specs[rec.norm(self.path(key))] = spec
            return fn(self, key, *args, **kwargs)

        wrapped.__name__ = fn.__name__
        return wrapped

    def leaves(self) -> set[str]:
        return {
            p
            for p in self.allowed
            if not any(q.startswith((p + ".", p + "[]")) for q in self.allowed)
        }


def _documented(page: Path) -> dict[str, list[str]]:
    """Key path → the cells of its row, from the tables of ``page`` (``a.{b, c}`` rows
    stand for ``a.b`` and ``a.c``)."""
    rows: dict[str, list[str]] = {}
    in_table = False
    for line in page.read_text().splitlines():
        in_table = line.startswith("| key |") or (in_table and line.startswith("|"))
        m = re.match(r"\| `([^`]+)` \|(.*)\|$", line)
        if not (in_table and m):
            continue
        key, cells = m.group(1), [c.strip() for c in re.split(r"(?<!\\)\|", m.group(2))]
        brace = re.fullmatch(r"(.*)\{(.*)\}(.*)", key)
        names = (
            [brace.group(1) + k.strip() + brace.group(3) for k in brace.group(2).split(",")]
            if brace
            else [key]
        )
        for name in names:
            assert name not in rows, f"{page.name}: {name} is listed twice"
            rows[name] = cells
    return rows


def _without(doc: Any, path: list[str]) -> bool:
    """Delete the key at ``path`` (``x[]`` steps into every item of list ``x``) from
    ``doc`` in place; whether anything was deleted."""
    head, rest = path[0], path[1:]
    items = head.endswith("[]")
    key = head.removesuffix("[]")
    if not isinstance(doc, dict) or key not in doc:
        return False
    if not rest:
        del doc[key]
        return True
    inner = doc[key] if items else [doc[key]]
    return any([_without(item, rest) for item in inner])


def _check_required(rows: dict[str, list[str]], docs: list[Any], parse: Any) -> None:
    """A key documented as required is refused when left out; one with a default is
    not."""
    for key, cells in rows.items():
        for doc in docs:
            trial = copy.deepcopy(doc)
            if not _without(trial, key.split(".")):
                continue
            if cells[2] == "required":
                with pytest.raises(GracenavError, match="missing key"):
                    parse(trial)
            elif cells[2]:  # a default: optional (an empty cell: needed by its section)
                parse(trial)


def _number(v: Any) -> str:
    return str(int(v)) if isinstance(v, int) and not isinstance(v, bool) else f"{v:g}"


def _check_rows(rec: _Recorder, rows: dict[str, list[str]], page: str) -> None:
    accepted = rec.leaves()
    assert set(rows) == accepted, (
        f"{page}: not documented: {sorted(accepted - set(rows))}; "
        f"documented but not accepted: {sorted(set(rows) - accepted)}"
    )
    for key, spec in rec.specs.items():
        if key not in rows:
            continue
        _type, unit, default, limits, _meaning = rows[key]
        d = spec.get("default", spec.get("value"))
        if isinstance(d, bool):
            assert default == str(d).lower(), (page, key, default)
        elif isinstance(d, str):
            assert default == f"`{d}`", (page, key, default)
        elif isinstance(d, int | float) and math.isfinite(d):
            assert default == _number(d), (page, key, default, d)
        if spec.get("unit"):
            assert unit == spec["unit"], (page, key, unit, spec["unit"])
        for bound in ("minimum", "maximum", "bound", "max_len"):
            v = spec.get(bound)
            if v is not None and math.isfinite(v) and not (bound == "minimum" and v == 0):
                assert _number(v) in limits, (page, key, bound, v, limits)
        if spec["kind"] == "choice":
            for option in spec.get("options", []) or []:
                assert f"`{option}`" in limits, (page, key, option)


_SCENARIOS = [
    {
        "name": "all keys, point to point",
        "map": {
            "bounds": [[0, 0], [4, 4]],
            "resolution": 0.05,
            "name": "m",
            "obstacles": [
                {"rectangle": {"min": [1, 1], "max": [1.2, 1.2]}},
                {"circle": {"center": [3, 3], "radius": 0.1}},
                {"polygon": {"points": [[2, 0.2], [2.4, 0.2], [2.2, 0.5]]}},
            ],
        },
        "robot": {"footprint_radius": 0.2, "sensing_range": 3.0},
        "planner": {
            "kind": "gracenav",
            "cost": "time",
            "max_halvings": 1,
            "resume_from_balancing": True,
            "capture": True,
            "seed": 0,
            "speed_clearance": 0.1,
            "memory_limit_gib": 2,
        },
        "task": {"kind": "point_to_point", "goal": [2, 2, 0, 0], "starts": [[0.5, 0.5, 0, 0]]},
        "moving_obstacles": [
            {"name": "p", "radius": 0.2, "path": [[3, 0], [3, 3]], "speed": 0.5, "appear": 1},
            {"radius": 0.2, "path": [[3, 0]], "leave": 5},
        ],
        "disturbances": [
            {"kind": "push", "time": 1.0, "impulse": [1.0, 0.0]},
            {"kind": "drag", "start_time": 1.0, "end_time": 2.0, "velocity": [0.1, 0.0]},
        ],
        "simulation": {
            "plant": "model3d",
            "seed": 0,
            "position_noise_std": 0.0,
            "max_time": 60,
            "plant_params": {"body_mass": 1.1},
        },
    },
    {
        "name": "surveillance, ROS map",
        "map": {"ros_map": "lab_ros.yaml"},
        "task": {"kind": "surveillance", "start": [0, 0, 0, 0], "goals": [[1, 0, 0.5, 0]]},
    },
]


def test_scenario_reference_lists_every_key(monkeypatch: pytest.MonkeyPatch) -> None:
    from gracenav.scenarios import parse_scenario
    from gracenav.world import load_map

    rec = _Recorder(monkeypatch)
    for doc in _SCENARIOS:
        scenario = parse_scenario(doc, base=ROOT / "examples" / "maps")
        if isinstance(scenario.map_source, dict):
            rec.prefix = "map."
            load_map(scenario.map_source)
            rec.prefix = ""
    rec.allowed.discard("map")  # an inline map's keys are read by the map loader
    rows = _documented(DOCS / "scenarios.md")
    _check_rows(rec, rows, "scenarios.md")

    def parse(doc: dict[str, Any]) -> None:
        scenario = parse_scenario(doc, base=ROOT / "examples" / "maps")
        if isinstance(scenario.map_source, dict):
            load_map(scenario.map_source)

    _check_required(rows, _SCENARIOS, parse)


def test_campaign_reference_lists_every_key(monkeypatch: pytest.MonkeyPatch) -> None:
    from gracenav.campaign import parse_campaign

    rec = _Recorder(monkeypatch)
    doc = {
        "name": "c",
        "seed": 1,
        "trials": 2,
        "planners": ["gracenav"],
        "scenario": "src/gracenav/data/scenarios/fig5_point_to_point.yaml",
        "push": {"impulse": [0, 16], "time": [1, 6]},
        "noise": [0.0],
        "plant_params": {"body_mass": [0.8, 1.2]},
        "pairs": {"clearance": 0.35, "min_distance": 2.0},
        "cluster": "tcp://10.0.0.5:8786",
    }
    parse_campaign(doc, base=ROOT)
    rec.allowed.discard("scenario")  # the base scenario: see the scenario reference
    rows = _documented(DOCS / "campaigns.md")
    _check_rows(rec, rows, "campaigns.md")
    _check_required(rows, [doc], lambda d: parse_campaign(d, base=ROOT))


# -- the API and command-line references ----------------------------------------------


def test_api_page_documents_the_public_api() -> None:
    import gracenav

    text = (DOCS / "api.md").read_text()
    shown = set(re.findall(r"^::: gracenav\.[\w.]*\.(\w+)$", text, flags=re.MULTILINE))
    public = set(gracenav.__all__) - {"__version__"}
    assert shown == public, (sorted(public - shown), sorted(shown - public))
    for line in re.findall(r"^::: (gracenav\.[\w.]+)$", text, flags=re.MULTILINE):
        module, name = line.rsplit(".", 1)
        assert getattr(gracenav, name) is getattr(__import__(module, fromlist=[name]), name)
    assert "`gracenav.__version__`" in text


def test_cli_reference_is_generated_from_the_parser() -> None:
    mkdocs_hooks = _hooks()
    page = (DOCS / "cli.md").read_text()
    assert page.count(mkdocs_hooks.MARKER) == 1
    text = mkdocs_hooks.on_page_markdown(page)
    names = [" ".join(("gracenav", *path)) for path, _ in mkdocs_hooks.commands()]
    assert {"gracenav run", "gracenav palette build", "gracenav plot recovery"} <= set(names)
    for name in names:
        assert f"`{name}`\n\n```text\nusage: {name}" in text, name


def test_make_targets_and_extras_shown_exist() -> None:
    """``make TARGET`` lines name targets of the Makefile; ``pip install
    'gracenav[EXTRA]'`` names extras of pyproject.toml."""
    import tomllib

    makefile = (ROOT / "Makefile").read_text()
    targets = set(re.findall(r"^([\w-]+):", makefile, flags=re.MULTILINE))
    shown = [words for _, line in _command_lines("make") for words in [shlex.split(line)[1:]]]
    assert shown
    for words in shown:
        for word in words:
            assert "=" in word or word in targets, (word, sorted(targets))
    extras = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"][
        "optional-dependencies"
    ]
    named = [m for p in PAGES for m in re.findall(r"gracenav\[(\w+)\]", p.read_text())]
    assert named and set(named) <= set(extras), (named, sorted(extras))


def test_readme_headline_figures_are_those_of_the_benchmarks_page() -> None:
    readme = (ROOT / "README.md").read_text()
    section = readme.split("\n## Headline figures\n", 1)[1].split("\n## ", 1)[0]
    rows = [line for line in section.splitlines() if line.startswith("| ")]
    assert len(rows) >= 5
    benchmarks = (DOCS / "benchmarks.md").read_text()
    for row in rows:
        assert row in benchmarks, row
