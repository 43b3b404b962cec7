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


def test_no_package_imports_a_later_layer():
    assert upward_imports() == []


def test_the_check_sees_an_upward_import_inside_a_function(tmp_path):
    module = tmp_path / "m.py"
    module.write_text("def f():\n    from drillgym.eval.suites import SUITES\n    return SUITES\n")
    assert imports_of(module) == [(2, "drillgym.eval.suites")]
