"""No import cycles among gracenav's modules.

Every import counts: at module level, inside functions and under ``TYPE_CHECKING``.
The graph is read from the source with :mod:`ast`, nothing is imported.
"""

from __future__ import annotations

import ast
from pathlib import Path

import gracenav

#: The import cycles still to be broken, as the sets of modules they run through: none.
#: A cycle not listed fails, and so does a listed one that is gone.
KNOWN_CYCLES: tuple[frozenset[str], ...] = ()


def _modules(root: Path, package: str) -> dict[str, tuple[Path, bool]]:
    """Dotted module name -> (file, whether it is a package's ``__init__``)."""
    out = {}
    for path in sorted(root.rglob("*.py")):
        parts = [package, *path.relative_to(root).with_suffix("").parts]
        is_package = parts[-1] == "__init__"
        if is_package:
            parts = parts[:-1]
        out[".".join(parts)] = (path, is_package)
    return out


def import_graph(root: Path, package: str) -> dict[str, set[str]]:
    """The modules of ``package`` (its sources under ``root``) each imports.

    ``from a.b import c`` imports module ``a.b.c`` if there is one, else ``a.b``; an
    import resolves to the longest module of the package its name starts with.
    """
    modules = _modules(root, package)

    def resolve(name: str) -> str | None:
        while name and name not in modules:
            name = name.rpartition(".")[0]
        return name or None

    graph: dict[str, set[str]] = {name: set() for name in modules}
    for name, (path, is_package) in modules.items():
        here = name if is_package else name.rpartition(".")[0]
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            targets: list[str] = []
            if isinstance(node, ast.Import):
                targets = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    parts = here.split(".")
                    base = ".".join(parts[: len(parts) - node.level + 1])
                    base = f"{base}.{node.module}" if node.module else base
                else:
                    base = node.module or ""
                targets = [
                    f"{base}.{alias.name}" if f"{base}.{alias.name}" in modules else base
                    for alias in node.names
                ]
            for target in targets:
                if target != package and not target.startswith(package + "."):
                    continue
                got = resolve(target)
                if got is not None and got != name:
                    graph[name].add(got)
    return graph


def cycles(graph: dict[str, set[str]]) -> list[frozenset[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    out: list[frozenset[str]] = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on_stack.add(v)
        for w in sorted(graph[v]):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on_stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = set()
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.add(w)
                if w == v:
                    break
            if len(component) > 1:
                out.append(frozenset(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def _describe(graph: dict[str, set[str]], component: frozenset[str]) -> str:
    return "; ".join(f"{a} -> {', '.join(sorted(graph[a] & component))}" for a in sorted(component))


def test_the_checker_finds_every_kind_of_import(tmp_path: Path) -> None:
    """A cycle closed by an import in a function, one under TYPE_CHECKING, a relative
    import and ``from package import module`` are all found; a one-way import is not a
    cycle."""
    pkg = tmp_path / "pkg"
    (pkg / "sub").mkdir(parents=True)
    (pkg / "__init__.py").write_text("")
    (pkg / "sub" / "__init__.py").write_text("")
    (pkg / "a.py").write_text("from pkg.b import thing\n")
    (pkg / "b.py").write_text("def f():\n    from pkg import a\n")
    (pkg / "c.py").write_text(
        "from typing import TYPE_CHECKING\nif TYPE_CHECKING:\n    import pkg.d\n"
    )
    (pkg / "d.py").write_text("from . import c\n")
    (pkg / "sub" / "e.py").write_text("from ..a import thing\nfrom .f import g\n")
    (pkg / "sub" / "f.py").write_text("from pkg.sub import e\n")
    (pkg / "g.py").write_text("import pkg.a\nimport numpy\n")
    graph = import_graph(pkg, "pkg")
    assert graph["pkg.sub.e"] == {"pkg.a", "pkg.sub.f"}
    assert graph["pkg.g"] == {"pkg.a"}
    assert sorted(sorted(c) for c in cycles(graph)) == [
        ["pkg.a", "pkg.b"],
        ["pkg.c", "pkg.d"],
        ["pkg.sub.e", "pkg.sub.f"],
    ]


def test_no_import_cycles_but_the_known_ones() -> None:
    """No cycle among gracenav's modules beyond :data:`KNOWN_CYCLES`, and each of those
    still exists (a broken one leaves the list)."""
    root = Path(gracenav.__file__).parent
    graph = import_graph(root, "gracenav")
    assert "gracenav.library" in graph["gracenav.execution.capture"]  # the graph is read at all
    found = cycles(graph)
    new = [_describe(graph, c) for c in found if c not in KNOWN_CYCLES]
    assert not new, f"import cycles: {new}"
    gone = [sorted(c) for c in KNOWN_CYCLES if c not in found]
    assert not gone, f"no longer cycles, remove them from KNOWN_CYCLES: {gone}"
