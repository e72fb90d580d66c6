"""The architecture's rules that import-linter (``make lint``) does not state itself.

The layering and independence contracts live in ``pyproject.toml`` ``[tool.importlinter]``.
Here, independently of it: no import cycle anywhere (every import statement, lazy ones
inside functions included), no package importing another package's private names, and
vendor SDKs imported only lazily.
"""

from __future__ import annotations

import ast
from collections.abc import Iterator
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("sim", "vision", "daq", "pipelines")


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def _modules() -> dict[str, Path]:
    return {_module_name(p): p for pkg in PACKAGES for p in sorted((ROOT / pkg).rglob("*.py"))}


def _imports(name: str, path: Path, known: set[str]) -> Iterator[tuple[str, str, int]]:
    """(imported module, imported name or "", line) for every import statement in the file,
    at any depth; relative imports resolved; ``from pkg import mod`` resolved to the module."""
    package = name if path.name == "__init__.py" else name.rpartition(".")[0]
    for node in ast.walk(ast.parse(path.read_text("utf-8"), filename=str(path))):
        if isinstance(node, ast.Import):
            for alias in node.names:
                yield alias.name, "", node.lineno
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[: len(anchor) - (node.level - 1)]
                base = ".".join([*anchor, base] if base else anchor)
            for alias in node.names:
                sub = f"{base}.{alias.name}"
                if sub in known:
                    yield sub, "", node.lineno
                else:
                    yield base, alias.name, node.lineno


def _graph() -> dict[str, set[str]]:
    modules = _modules()
    known = set(modules)
    graph: dict[str, set[str]] = {m: set() for m in modules}
    for name, path in modules.items():
        for target, _, _ in _imports(name, path, known):
            if target in known and target != name:
                graph[name].add(target)
    return graph


def _cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components with more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

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
            component = []
            while True:
                w = stack.pop()
                on_stack.discard(w)
                component.append(w)
                if w == v:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return found


def test_the_walk_sees_lazy_and_relative_imports(tmp_path: Path) -> None:
    path = tmp_path / "mod.py"
    path.write_text(
        "import numpy\ndef f():\n    from sim.models import fe\n    from .sibling import thing\n"
    )
    found = {(t, n) for t, n, _ in _imports("sim.solvers.mod", path, {"sim.models.fe"})}
    assert found == {("numpy", ""), ("sim.models.fe", ""), ("sim.solvers.sibling", "thing")}


def test_no_module_takes_part_in_an_import_cycle() -> None:
    cycles = _cycles(_graph())
    assert not cycles, "import cycles:\n" + "\n".join(" <-> ".join(c) for c in cycles)


def test_a_cycle_is_found_when_there_is_one() -> None:
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert _cycles(graph) == [["a", "b", "c"]]


def test_no_package_imports_another_packages_private_names() -> None:
    modules = _modules()
    offenders = []
    for name, path in modules.items():
        top = name.split(".")[0]
        for target, imported, line in _imports(name, path, set(modules)):
            target_top = target.split(".")[0]
            if target_top not in PACKAGES or target_top == top:
                continue
            private_module = any(part.startswith("_") for part in target.split(".")[1:])
            if private_module or (imported.startswith("_") and imported != "__version__"):
                offenders.append(f"{path.relative_to(ROOT)}:{line} imports {target} {imported}")
    assert not offenders, "\n".join(offenders)


def test_vendor_sdks_are_imported_lazily() -> None:
    """nidaqmx is optional hardware support: only inside the functions that need it."""
    for name, path in _modules().items():
        tree = ast.parse(path.read_text("utf-8"))
        for node in tree.body:
            names = []
            if isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = [node.module or ""]
            assert not any(n.split(".")[0] == "nidaqmx" for n in names), (
                f"{name}: nidaqmx must be imported lazily inside a function"
            )
