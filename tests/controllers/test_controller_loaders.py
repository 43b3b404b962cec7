"""Spec families built by a loader (``table:PATH``, ``residual:PATH``): the registry never imports a layer above it.

``drillgym.training`` registers ``residual`` when it is imported; ``drillgym.eval`` imports it, so every job and the
``drillgym`` command build residual controllers. A fresh interpreter that imports only ``drillgym.controllers`` shows
what the registry alone knows (a subprocess: in this one the test suite has imported training long ago).
"""

import subprocess
import sys

import pytest

from drillgym.controllers import registry
from drillgym.controllers.plan_schedule import PlanScheduledController
from drillgym.envs.errors import UserError


def _fresh(code: str) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=False)


def test_the_controllers_layer_alone_names_the_package_that_registers_residual_specs():
    result = _fresh(
        "import sys\n"
        "from drillgym.controllers import make_controller\n"
        "try:\n"
        "    make_controller('residual:shipped')\n"
        "except ValueError as e:\n"
        "    print(type(e).__name__, e)\n"
        "print('drillgym.training' in sys.modules)\n"
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.splitlines() == [
        "UserError residual:... controllers are registered by drillgym.training: import drillgym.training first",
        "False",
    ]


def test_importing_drillgym_eval_registers_residual_specs_for_every_job():
    result = _fresh(
        "import drillgym.eval\n"
        "from drillgym.controllers import make_controller\n"
        "print(type(make_controller('residual:shipped')).__name__)\n"
    )
    assert result.returncode == 0, result.stderr
    assert result.stdout.split() == ["PlanScheduledController"]


def test_the_table_family_is_built_in():
    assert registry.loaders()["table"] == "drillgym.controllers.schedule_table:load_table_controller"
    assert isinstance(registry.make_controller("table:shipped"), PlanScheduledController)


def test_a_registered_loader_builds_its_specs_and_wins_over_an_entry_point(monkeypatch):
    monkeypatch.setattr(registry, "_registered", {})
    monkeypatch.setattr(registry, "_merged", None)  # restored, with the cache of before, at the test's end
    monkeypatch.setattr(registry, "_entry_point_loaders", lambda: {"mine": "no_such_module:nothing"})
    assert registry.loaders()["mine"] == "no_such_module:nothing"
    registry.register_loader("mine", "drillgym.controllers.schedule_table:load_table_controller")
    assert isinstance(registry.make_controller("mine:shipped"), PlanScheduledController)
    with pytest.raises(ValueError, match="module:function"):
        registry.register_loader("bad", "no_colon")
    with pytest.raises(TypeError):
        registry.loaders()["mine"] = "x"  # read-only: the merged table is shared


def test_an_unknown_family_lists_the_loaders():
    with pytest.raises(UserError, match=r"unknown controller 'nope'.*table:\.\.\."):
        registry.make_controller("nope")
