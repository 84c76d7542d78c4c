"""The layering of DESIGN.md, enforced: no module imports a higher layer, and no import circle.

Every import counts, at module level or inside a function (an import inside a function is still a
dependency; hiding one there is how the old circle through 16 files held together).
"""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1] / "jaxmotion"

LAYERS = (
    "config",
    "physics",
    "motion",
    "tasks",
    "envs",
    "nets",
    "algos",
    "training",
    "viz",
    "evaluation",
    "export",
    "",
)
"""Bottom to top; a module may import its own layer and the layers below it. "" is the entry
points at the top of the package (train, eval, bench, plot, play); ``export`` is the policy
exporter's entry point with its pieces."""


def module_name(path: Path) -> str:
    parts = list(path.relative_to(ROOT.parent).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def modules() -> dict[str, Path]:
    return {module_name(p): p for p in ROOT.rglob("*.py")}


def imports_of(path: Path, known: set[str]) -> set[str]:
    """The jaxmotion modules a file imports (anywhere in it), resolved to modules in ``known``."""
    out = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and node.level == 0:
            # `from pkg import name`: the submodule pkg.name if there is one, else pkg itself
            names = [
                f"{node.module}.{a.name}" if f"{node.module}.{a.name}" in known else node.module for a in node.names
            ]
        else:
            continue
        for n in names:
            if n.split(".")[0] != "jaxmotion":
                continue
            while n not in known and "." in n:
                n = n.rsplit(".", 1)[0]
            if n in known:
                out.add(n)
    return out


def import_graph() -> dict[str, set[str]]:
    mods = modules()
    known = set(mods)
    return {m: imports_of(p, known) - {m} for m, p in mods.items()}


def layer_of(module: str) -> int:
    parts = module.split(".")
    name = parts[1] if len(parts) > 2 or (len(parts) == 2 and parts[1] in LAYERS) else ""
    if name not in LAYERS:
        raise KeyError(f"{module} is in no layer; add its package to LAYERS in {__file__}")
    return LAYERS.index(name)


def upward_imports(graph: dict[str, set[str]]) -> list[str]:
    return sorted(
        f"{a} ({LAYERS[layer_of(a)] or 'entry'}) imports {b} ({LAYERS[layer_of(b)] or 'entry'})"
        for a, deps in graph.items()
        for b in deps
        if layer_of(b) > layer_of(a)
    )


def import_cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """Strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out, counter = {}, {}, [], set(), [], [0]

    def visit(v):
        index[v] = low[v] = counter[0]
        counter[0] += 1
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            comp = []
            while True:
                w = stack.pop()
                on.discard(w)
                comp.append(w)
                if w == v:
                    break
            if len(comp) > 1:
                out.append(sorted(comp))

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_every_module_has_a_layer_and_every_layer_has_modules():
    """``layer_of`` raises for a module outside the layers; every listed layer holds modules (a
    renamed package would otherwise leave its layer empty and its modules unchecked)."""
    found = {layer_of(m) for m in modules()}
    assert found == set(range(len(LAYERS)))
    assert layer_of("jaxmotion.train") == len(LAYERS) - 1 and layer_of("jaxmotion.config.errors") == 0


def test_no_module_imports_a_higher_layer():
    assert upward_imports(import_graph()) == []


def test_no_import_circle():
    assert import_cycles(import_graph()) == []


def test_the_layering_test_catches_a_deliberate_upward_import_and_a_circle():
    """The checks on the real graph with one bad edge added: motion importing the learner
    (upward), and the learner's import made mutual (a circle)."""
    graph = import_graph()
    assert "jaxmotion.training.learner" in graph and "jaxmotion.motion.clip" in graph
    bad = {k: set(v) for k, v in graph.items()}
    bad["jaxmotion.motion.clip"].add("jaxmotion.training.learner")
    assert upward_imports(bad) == ["jaxmotion.motion.clip (motion) imports jaxmotion.training.learner (training)"]
    assert any("jaxmotion.motion.clip" in c and "jaxmotion.training.learner" in c for c in import_cycles(bad))
    with pytest.raises(KeyError, match="no layer"):
        layer_of("jaxmotion.newpackage.thing")


def test_imports_inside_functions_count(tmp_path):
    f = tmp_path / "m.py"
    f.write_text("def f():\n    from jaxmotion.training import learner\n    import jaxmotion.viz.render\n")
    assert imports_of(f, {"jaxmotion.training.learner", "jaxmotion.viz.render", "jaxmotion.training"}) == {
        "jaxmotion.training.learner",
        "jaxmotion.viz.render",
    }
