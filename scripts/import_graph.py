"""The import graph of fluidnexus and its CLI, read from the source with ``ast`` (nothing is imported).

Prints each package with its lines of code, every import that runs up the layers (docs/architecture.md), and
every cycle between modules. ``tests/test_layers.py`` holds both at zero.

    python scripts/import_graph.py
"""
from __future__ import annotations

import ast
import sys
from collections import defaultdict
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
TOP = ("fluidnexus", "cli")
# layers from the top down; a module may import its own layer and the ones below it
PIPELINES = ("calibrate", "gen", "recon", "predict", "diagnose", "batch", "evaluation", "render_run", "viewer")
LAYERS = ("cli", "pipelines", "scene", "engine")


def layer(module: str) -> str:
    """The layer of a module: ``cli``, ``pipelines``, ``scene`` (scene, scenery and IO) or ``engine``."""
    parts = module.split(".")
    if parts[0] == "cli":
        return "cli"
    if len(parts) > 1 and parts[1] == "engine":
        return "engine"
    if len(parts) > 1 and parts[1] in PIPELINES:
        return "pipelines"
    return "scene"


def modules(root: Path = ROOT) -> dict[str, Path]:
    """Dotted module name -> file, for every module of the packages in ``TOP``."""
    out = {}
    for top in TOP:
        for path in sorted((root / top).rglob("*.py")):
            name = ".".join(path.relative_to(root).with_suffix("").parts)
            out[name.removesuffix(".__init__")] = path
    return out


def _targets(name: str, path: Path, node: ast.AST, known: dict) -> list[str]:
    if isinstance(node, ast.Import):
        found = [a.name for a in node.names]
    else:
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        base = package.split(".")
        base = ".".join(base[:len(base) - node.level + 1]) if node.level else ""
        mod = ".".join(p for p in (base, node.module or "") if p)
        found = [f"{mod}.{a.name}" if f"{mod}.{a.name}" in known else mod for a in node.names]
    out = []
    for target in found:
        while target and target not in known and "." in target:
            target = target.rpartition(".")[0]
        if target in known and target != name:
            out.append(target)
    return out


def _type_checking(node: ast.AST) -> bool:
    return isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test)


def edges(known: dict[str, Path]) -> dict[str, set[str]]:
    """Module -> the modules it imports (at the top or inside functions; not under ``TYPE_CHECKING``)."""
    graph = defaultdict(set)
    for name, path in known.items():
        skip = set()
        for node in ast.walk(ast.parse(path.read_text())):
            if _type_checking(node):
                skip.update(id(n) for n in ast.walk(node))
            if isinstance(node, (ast.Import, ast.ImportFrom)) and id(node) not in skip:
                graph[name].update(_targets(name, path, node, known))
    return graph


def upward(graph: dict[str, set[str]]) -> list[tuple[str, str]]:
    """Imports from a module into a layer above its own."""
    rank = {name: i for i, name in enumerate(LAYERS)}
    return sorted((a, b) for a, targets in graph.items() for b in targets if rank[layer(b)] < rank[layer(a)])


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v):
        index[v] = low[v] = len(index)
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

    sys.setrecursionlimit(10_000)
    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def package_lines(known: dict[str, Path]) -> dict[str, int]:
    """Lines of code per package (a top-level module counts as its own)."""
    lines = defaultdict(int)
    for name, path in known.items():
        parts = name.split(".")
        key = ".".join(parts[:2]) if len(parts) > 1 else parts[0]
        lines[key] += len(path.read_text().splitlines())
    return dict(lines)


def main() -> int:
    known = modules()
    graph = edges(known)
    for package, n in sorted(package_lines(known).items(), key=lambda kv: (LAYERS.index(layer(kv[0])), kv[0])):
        print(f"{layer(package):10s} {package:36s} {n:6d} lines")
    up, loops = upward(graph), cycles(graph)
    print(f"\nimports that run up the layers: {len(up)}")
    for a, b in up:
        print(f"  {a} ({layer(a)}) -> {b} ({layer(b)})")
    print(f"cycles between modules: {len(loops)}")
    for comp in loops:
        print("  " + " <-> ".join(comp))
    return 0


if __name__ == "__main__":
    sys.exit(main())
