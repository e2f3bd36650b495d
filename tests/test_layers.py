"""The layers of rbody go one way (docs/design.md): no import cycle anywhere in rbody/, the engine never imports
the scene layer, the families, the MJCF reader or simulate, and validation uses rbody's public names only.

The imports are read from the source (every `import` and `from ... import`, at module level or inside a
function, since a deferred import is still a dependency), so the test sees what a reader of the code sees."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def modules(package: str) -> dict[str, Path]:
    return {module_name(path): path for path in sorted((ROOT / package).rglob("*.py"))}


def imported(path: Path, known: dict[str, Path]) -> set[str]:
    """The modules of `known` that the file at `path` imports: `from P import name` names the submodule P.name
    where there is one, else P itself (its __init__); relative imports are resolved against the file's package."""
    tree = ast.parse(path.read_text(), filename=str(path))
    here = module_name(path)
    package = here if path.name == "__init__.py" else here.rpartition(".")[0]
    found: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            found.update(alias.name for alias in node.names if alias.name in known)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                anchor = package.split(".")
                anchor = anchor[:len(anchor) - (node.level - 1)]
                base = ".".join(anchor + ([base] if base else []))
            for alias in node.names:
                submodule = f"{base}.{alias.name}"
                if submodule in known:
                    found.add(submodule)
                elif base in known:
                    found.add(base)
    found.discard(here)
    return found


def graph(package: str) -> dict[str, set[str]]:
    known = modules(package)
    return {name: imported(path, known) for name, path in known.items()}


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan), each a set of modules that import
    each other, directly or through others."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on_stack: set[str] = set()
    found: list[list[str]] = []

    def visit(node: str) -> None:
        index[node] = low[node] = len(index)
        stack.append(node)
        on_stack.add(node)
        for target in sorted(edges.get(node, ())):
            if target not in index:
                visit(target)
                low[node] = min(low[node], low[target])
            elif target in on_stack:
                low[node] = min(low[node], index[target])
        if low[node] == index[node]:
            component = []
            while True:
                member = stack.pop()
                on_stack.discard(member)
                component.append(member)
                if member == node:
                    break
            if len(component) > 1:
                found.append(sorted(component))

    for node in sorted(edges):
        if node not in index:
            visit(node)
    return found


def test_the_cycle_finder_finds_a_cycle():
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_no_import_cycle_in_rbody():
    assert cycles(graph("rbody")) == []


ABOVE_THE_ENGINE = ("rbody.scene", "rbody.scenes", "rbody.mjcf", "rbody.simulation")


@pytest.mark.parametrize("module", sorted(name for name in modules("rbody") if name.startswith("rbody.engine")))
def test_the_engine_imports_nothing_above_it(module):
    above = sorted(target for target in graph("rbody")[module]
                   if target == "rbody" or any(target == a or target.startswith(a + ".") for a in ABOVE_THE_ENGINE))
    assert above == [], f"{module} imports {above}, which sit above the engine"


def test_the_description_layer_imports_no_engine_or_scene():
    edges = graph("rbody")
    assert {t for t in edges["rbody.layout"] if t.startswith(("rbody.engine", "rbody.scene", "rbody.mjcf"))} == set()


def test_validation_uses_public_rbody_names_only():
    private = []
    for path in sorted((ROOT / "validation").rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            names = []
            if isinstance(node, ast.ImportFrom) and (node.module or "").startswith("rbody"):
                names = [node.module] + [f"{node.module}.{a.name}" for a in node.names]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names if a.name.startswith("rbody")]
            private += [f"{path.relative_to(ROOT)}: {n}" for n in names if any(p.startswith("_") for p in n.split("."))]
    assert private == []
