"""The public API: every name in gracenav.__all__ resolves, nothing else does, and type
checkers see each re-export's real type; the README's library example uses it alone."""

from __future__ import annotations

import ast
import re
import sys
from pathlib import Path

import pytest

import gracenav

ROOT = Path(__file__).resolve().parents[1]


def test_every_public_name_resolves() -> None:
    for name in gracenav.__all__:
        assert getattr(gracenav, name) is not None
    assert set(gracenav.__all__) <= set(dir(gracenav))


def test_unknown_name() -> None:
    with pytest.raises(AttributeError, match="no attribute 'teleport'"):
        gracenav.teleport  # noqa: B018


def test_all_is_sorted_and_the_typed_imports_match_the_lazy_table() -> None:
    """``__all__`` is sorted and holds the eager names and the lazy table's; the
    ``if TYPE_CHECKING:`` block imports each lazy name from its table's module."""
    assert gracenav.__all__ == sorted(gracenav.__all__)
    lazy = gracenav._LAZY
    tree = ast.parse(Path(gracenav.__file__).read_text())
    typed: dict[str, str] = {}
    eager: set[str] = {"__version__"}
    for node in tree.body:
        if isinstance(node, ast.If) and ast.unparse(node.test) == "TYPE_CHECKING":
            for imp in node.body:
                assert isinstance(imp, ast.ImportFrom) and imp.module is not None
                for alias in imp.names:
                    assert alias.asname is None
                    typed[alias.name] = imp.module
        elif isinstance(node, ast.ImportFrom) and node.module not in ("__future__", "typing"):
            eager.update(a.name for a in node.names)
    assert typed == lazy
    assert set(gracenav.__all__) == eager | set(lazy)
    assert len(gracenav.__all__) == len(set(gracenav.__all__))


def test_public_api_is_typed(tmp_path: Path) -> None:
    """mypy sees the real type of every name in ``gracenav.__all__`` (not ``Any``, which a
    bare module ``__getattr__`` would give) and reports a misuse of one."""
    api = pytest.importorskip("mypy.api")
    names = gracenav.__all__
    lines = ["import gracenav", ""]
    lines += [f"reveal_type(gracenav.{name})" for name in names]
    lines.append("controller: int = gracenav.HybridController  # a deliberate error")
    snippet = tmp_path / "snippet.py"
    snippet.write_text("\n".join(lines) + "\n")
    src = Path(gracenav.__file__).resolve().parents[1]
    config = [
        "[mypy]",
        "ignore_missing_imports = True",
        "follow_imports = silent",  # the package itself is checked by the project's mypy run
        f"cache_dir = {tmp_path / 'mypy_cache'}",
    ]
    if not {"site-packages", "dist-packages"} & set(src.parts):
        config.append(f"mypy_path = {src}")  # this checkout, not another installed copy
    (tmp_path / "mypy.ini").write_text("\n".join(config) + "\n")
    limit = sys.getrecursionlimit()
    try:  # mypy raises the interpreter's recursion limit in-process: put it back
        out, err, _ = api.run(["--config-file", str(tmp_path / "mypy.ini"), str(snippet)])
    finally:
        sys.setrecursionlimit(limit)
    assert err == ""
    revealed: dict[int, str] = {}
    for line in out.splitlines():
        m = re.match(r".*snippet\.py:(\d+): note: Revealed type is \"(.*)\"$", line)
        if m:
            revealed[int(m.group(1))] = m.group(2)
    for k, name in enumerate(names):
        seen = revealed.get(k + 3)
        assert seen is not None, (name, out)
        if name == "__version__":
            assert seen == "str"
            continue
        assert seen.startswith(("def ", "Overload(")), (name, seen)  # a function or a class
        if name[0].isupper():
            assert seen.endswith(f".{name}"), (name, seen)  # a class: returns its instances
    assert f"snippet.py:{len(names) + 3}: error: Incompatible types in assignment" in out
    assert out.count(": error:") == 1, out


def _readme_library_example() -> str:
    text = (ROOT / "README.md").read_text()
    section = text.split("\n## Library\n", 1)[1].split("\n## ", 1)[0]
    blocks = re.findall(r"```python\n(.*?)```", section, flags=re.DOTALL)
    assert len(blocks) == 2  # the library, then the same controller tick by tick
    return "\n".join(blocks)


def test_readme_library_example_imports_only_gracenav() -> None:
    tree = ast.parse(_readme_library_example())
    imports = [n for n in ast.walk(tree) if isinstance(n, ast.Import | ast.ImportFrom)]
    assert imports
    for node in imports:
        if isinstance(node, ast.ImportFrom):
            assert node.module == "gracenav" and node.level == 0
        else:
            assert [a.name for a in node.names] == ["gracenav"]


def test_readme_library_example_runs() -> None:
    namespace: dict[str, object] = {"__name__": "readme_example"}
    exec(compile(_readme_library_example(), "README.md", "exec"), namespace)
    assert namespace["episode"].status.value == "goal_reached"  # type: ignore[attr-defined]
    assert namespace["cmd"].status.value == "goal_reached"  # type: ignore[attr-defined]


def test_examples_run_headless(capsys) -> None:
    import runpy

    script = ROOT / "examples" / "navigate.py"
    runpy.run_path(str(script), run_name="__main__")
    assert "goal_reached" in capsys.readouterr().out
