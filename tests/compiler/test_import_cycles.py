"""The modules of armbench import one another without cycles.

A cycle hidden behind ``if TYPE_CHECKING:`` or an import inside a function still ties the
modules together: neither can be understood, tested or moved without the other, and the first
change that imports at module level turns it into an ImportError at start-up. So the graph is
built from every import statement in the source (module level, TYPE_CHECKING blocks and
function bodies alike), with Python's own ``ast`` module, and must be acyclic. Each module is
also imported on its own in a fresh interpreter, which a cycle at module level would break.
"""

from __future__ import annotations

import ast
import subprocess
import sys
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[2] / "sim" / "armbench"


def module_name(path: Path) -> str:
    rel = path.relative_to(PACKAGE.parent).with_suffix("")
    parts = list(rel.parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


def modules() -> dict[str, Path]:
    return {module_name(p): p for p in sorted(PACKAGE.rglob("*.py"))}


def _resolve(current: str, is_package: bool, level: int, target: str | None) -> str:
    base = current.split(".") if is_package else current.split(".")[:-1]
    if level > 1:
        base = base[:len(base) - (level - 1)]
    return ".".join([*base, *([target] if target else [])])


def imports_of(name: str, path: Path, known: set[str]) -> set[str]:
    """The armbench modules ``name`` imports anywhere in its source. ``from pkg import x`` is an
    edge to the submodule pkg.x when there is one, else to pkg itself."""
    tree = ast.parse(path.read_text(encoding="utf-8"), str(path))
    is_package = path.name == "__init__.py"
    out: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names if a.name.split(".")[0] == "armbench"}
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                mod = _resolve(name, is_package, node.level, node.module)
            elif node.module and node.module.split(".")[0] == "armbench":
                mod = node.module
            else:
                continue
            subs = {f"{mod}.{a.name}" for a in node.names} & known
            out |= subs
            if len(subs) < len(node.names):
                out.add(mod)
    return (out & known) - {name}


def import_graph() -> dict[str, set[str]]:
    mods = modules()
    known = set(mods)
    return {name: imports_of(name, path, known) for name, path in mods.items()}


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    on_stack: set[str] = set()
    stack: list[str] = []
    found: list[list[str]] = []
    counter = 0
    for root in sorted(graph):
        if root in index:
            continue
        work = [(root, iter(sorted(graph[root])))]
        index[root] = low[root] = counter
        counter += 1
        stack.append(root)
        on_stack.add(root)
        while work:
            node, children = work[-1]
            child = next(children, None)
            if child is not None:
                if child not in index:
                    index[child] = low[child] = counter
                    counter += 1
                    stack.append(child)
                    on_stack.add(child)
                    work.append((child, iter(sorted(graph[child]))))
                elif child in on_stack:
                    low[node] = min(low[node], index[child])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[node])
            if low[node] == index[node]:
                group = []
                while True:
                    m = stack.pop()
                    on_stack.discard(m)
                    group.append(m)
                    if m == node:
                        break
                if len(group) > 1:
                    found.append(sorted(group))
    return found


def test_the_graph_sees_imports_of_every_kind() -> None:
    # The checker itself: a TYPE_CHECKING import, a lazy one and a `from . import x` all count.
    graph = import_graph()
    assert "armbench.compiler.ffi" in graph["armbench.compiler.driver"]  # TYPE_CHECKING + lazy
    assert "armbench.compiler.ast" in graph["armbench.compiler.driver"]  # from . import ast
    assert "armbench.compiler.emit_c" in graph["armbench.compiler.build"]
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_armbench_imports_without_cycles() -> None:
    found = cycles(import_graph())
    assert found == [], f"import cycles: {found}"


_IMPORT_EACH = """
import importlib, sys, traceback
failed = []
for name in sys.argv[1:]:
    for loaded in [m for m in sys.modules if m == "armbench" or m.startswith("armbench.")]:
        del sys.modules[loaded]  # each module first, as if it were the only import
    try:
        importlib.import_module(name)
    except Exception:
        failed.append(name + ": " + traceback.format_exc(limit=3))
print("\\n".join(failed))
sys.exit(1 if failed else 0)
"""


def test_each_module_imports_first() -> None:
    # One interpreter, armbench's modules dropped from sys.modules before each: a module that
    # only imports when another one was imported before it fails here.
    names = sorted(m for m in modules() if m.startswith("armbench.compiler")
                   or m in ("armbench.locate", "armbench.cli", "armbench.export"))
    proc = subprocess.run([sys.executable, "-c", _IMPORT_EACH, *names], capture_output=True,
                          text=True, cwd=PACKAGE.parent)
    assert proc.returncode == 0, proc.stdout[-3000:] + proc.stderr[-2000:]
