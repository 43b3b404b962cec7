"""One import direction: envs <- controllers <- training <- eval, counting imports inside functions too."""

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LAYERS = ("envs", "controllers", "training", "eval")
"""Lowest first: a package may import its own layer and those before it, never one after it."""


def imports_of(path: Path) -> list[tuple[int, str]]:
    """Every absolute import in a module, with its line (module level, functions and classes alike)."""
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.append((node.lineno, node.module))
    return found


def upward_imports() -> list[str]:
    """``file:line module`` of every import that points to a later layer."""
    out = []
    for rank, layer in enumerate(LAYERS):
        for path in sorted((ROOT / layer).rglob("*.py")):
            for line, module in imports_of(path):
                parts = module.split(".")
                if parts[0] == "drillgym" and len(parts) > 1 and parts[1] in LAYERS[rank + 1 :]:
                    out.append(f"{path.relative_to(ROOT)}:{line} {module}")
    return out


def module_graph() -> dict[str, set[str]]:
    """Project module -> the project modules it imports (a package's own ``__init__`` not counted)."""
    modules = {}
    for layer in LAYERS:
        for path in (ROOT / layer).rglob("*.py"):
            name = ".".join(("drillgym", *path.relative_to(ROOT).with_suffix("").parts)).removesuffix(".__init__")
            modules[name] = path
    graph: dict[str, set[str]] = {}
    for name, path in modules.items():
        targets = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets |= {a.name for a in node.names}
            elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
                targets |= {node.module} | {f"{node.module}.{a.name}" for a in node.names}
        graph[name] = {t for t in targets if t in modules and t != name and not name.startswith(t + ".")}
    return graph


def import_circles(graph: dict[str, set[str]]) -> list[set[str]]:
    """The strongly connected components of more than one module (Tarjan)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    circles = []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        for w in graph[v]:
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in stack:
                low[v] = min(low[v], index[w])
        if low[v] == index[v]:
            component = set()
            while True:
                w = stack.pop()
                component.add(w)
                if w == v:
                    break
            if len(component) > 1:
                circles.append(component)

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return circles


def test_no_import_circles():
    assert import_circles(module_graph()) == []


def test_the_circle_finder_finds_a_circle():
    graph = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}
    assert import_circles(graph) == [{"a", "b", "c"}]


def test_no_package_imports_a_later_layer():
    assert upward_imports() == []


def test_the_check_sees_an_upward_import_inside_a_function(tmp_path):
    module = tmp_path / "m.py"
    module.write_text("def f():\n    from drillgym.eval.bench.suites import SUITES\n    return SUITES\n")
    assert imports_of(module) == [(2, "drillgym.eval.bench.suites")]


def cli_modules() -> set[str]:
    """The modules behind ``drillgym`` sub-commands, the front itself and ``python -m`` entry points."""
    from drillgym.eval.cli import COMMANDS

    mains = {name for name in module_graph() if name.endswith(".__main__")}
    return {module for module, _ in COMMANDS.values()} | {"drillgym.eval.cli"} | mains


def test_no_library_module_imports_a_command_module():
    cli = cli_modules()
    offenders = sorted(
        f"{name} -> {target}" for name, targets in module_graph().items() if name not in cli for target in targets & cli
    )
    assert offenders == []
