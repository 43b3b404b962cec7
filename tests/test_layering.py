"""One import direction: envs <- controllers <- training <- eval, counting imports inside functions too."""

import ast
import re
from importlib.metadata import distribution
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LAYERS = ("envs", "controllers", "training", "eval")
"""Lowest first: a package may import its own layer and those before it, never one after it."""


def imports_of(path: Path) -> list[tuple[int, str]]:
    """Every absolute import in a module, with its line (module level, functions and classes alike).

    Imports by name at run time count too: ``importlib.import_module("...")`` with a literal name, and a
    ``"module:function"`` loader target written as a literal (a registry imports it when a spec asks for it).
    """
    found = []
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            found += [(node.lineno, a.name) for a in node.names]
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            found.append((node.lineno, node.module))
        elif isinstance(node, ast.Call) and _called_name(node.func) == "import_module" and node.args:
            arg = node.args[0]
            if isinstance(arg, ast.Constant) and isinstance(arg.value, str):
                found.append((node.lineno, arg.value))
        elif isinstance(node, ast.Constant) and isinstance(node.value, str) and LOADER_TARGET.fullmatch(node.value):
            found.append((node.lineno, node.value.partition(":")[0]))
    return found


LOADER_TARGET = re.compile(r"drillgym(\.\w+)+:\w+")
"""A ``"module:function"`` target of the project's own code."""


def _called_name(func: ast.expr) -> str:
    return func.attr if isinstance(func, ast.Attribute) else func.id if isinstance(func, ast.Name) else ""


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


ENTRY_POINT_CONSUMERS = {"drillgym.controllers": "controllers"}
"""Entry-point groups of this project and the layer that imports their targets at run time."""


def upward_entry_points(entry_points: list[tuple[str, str, str]]) -> list[str]:
    """``group name = target`` of every ``(group, name, target)`` entry point whose target lies in a later layer
    than the one that loads it (scripts, which a user starts, are not loaded by a layer)."""
    out = []
    for group, name, target in entry_points:
        if group in ("console_scripts", "gui_scripts"):
            continue
        consumer = ENTRY_POINT_CONSUMERS.get(group)
        assert consumer is not None, f"entry-point group {group!r}: add the layer that loads it"
        parts = target.partition(":")[0].split(".")
        if parts[0] == "drillgym" and parts[1] in LAYERS[LAYERS.index(consumer) + 1 :]:
            out.append(f"{group} {name} = {target}")
    return out


def test_no_entry_point_makes_a_layer_load_a_later_one_at_run_time():
    installed = [(ep.group, ep.name, ep.value) for ep in distribution("drillgym").entry_points]
    assert any(group == "console_scripts" for group, _, _ in installed)  # the metadata is there to check
    assert upward_entry_points(installed) == []


def test_the_check_sees_runtime_imports_by_name(tmp_path):
    module = tmp_path / "m.py"
    module.write_text(
        "import importlib\n"
        "LOADERS = {'residual': 'drillgym.training.residual_policy:load_residual_controller'}\n"
        "def f():\n    return importlib.import_module('drillgym.eval.bench.suites')\n"
    )
    assert imports_of(module) == [
        (1, "importlib"),
        (2, "drillgym.training.residual_policy"),
        (4, "drillgym.eval.bench.suites"),
    ]
    entry_points = [
        ("drillgym.controllers", "residual", "drillgym.training.residual_policy:load_residual_controller"),
        ("drillgym.controllers", "table", "drillgym.controllers.schedule_table:load_table_controller"),
        ("console_scripts", "drillgym", "drillgym.eval.cli:main"),
    ]
    assert upward_entry_points(entry_points) == [
        "drillgym.controllers residual = drillgym.training.residual_policy:load_residual_controller"
    ]


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
