"""One import name: ``drillgym``; the four folders are its sub-packages and nothing else is installed."""

import subprocess
import sys
from pathlib import Path

from test_layering import LAYERS as PARTS
from test_layering import imports_of

ROOT = Path(__file__).resolve().parents[1]


def _python(code: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-c", code], cwd=cwd, capture_output=True, text=True, timeout=300)


def test_drillgym_works_beside_a_users_own_envs_package(tmp_path):
    (tmp_path / "envs").mkdir()
    (tmp_path / "envs" / "__init__.py").write_text("MINE = True\n")
    code = """
import gymnasium as gym
import drillgym
env = gym.make("drillgym/UR5BoneDrill-v1")
obs, _ = env.reset(seed=0)
import envs
assert envs.MINE, "the user's own envs package"
assert drillgym.envs.__name__ == "drillgym.envs"
print("ok", drillgym.__version__)
"""
    proc = _python(code, tmp_path)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "ok" in proc.stdout


def test_gym_make_imports_drillgym_from_the_id():
    proc = _python(
        'import gymnasium as gym; gym.make("drillgym:drillgym/UR5BoneDrill-v1").reset(seed=0)', ROOT / "docs"
    )
    assert proc.returncode == 0, proc.stderr[-3000:]


def test_no_top_level_envs_or_eval_module_is_installed(tmp_path):
    for name in PARTS:
        proc = _python(f"import {name}", tmp_path)
        assert proc.returncode != 0 and "ModuleNotFoundError" in proc.stderr, name


def test_the_project_imports_its_parts_only_through_drillgym():
    bare = [
        f"{path.relative_to(ROOT)}:{line} {module}"
        for path in ROOT.glob("*/**/*.py")
        if path.parts[len(ROOT.parts)] not in (".venv", "src", "runs", "results")
        for line, module in imports_of(path)
        if module.split(".")[0] in PARTS
    ]
    assert not bare, bare


def test_the_v0_ids_name_v1_when_made():
    import gymnasium as gym
    import pytest

    import drillgym

    assert drillgym.envs.ENV_IDS == [drillgym.envs.SIM_ENV_ID] and drillgym.envs.SIM_ENV_ID.endswith("-v1")
    for old in ("drillgym/UR5BoneDrill-v0", "drillgym/UR5BoneDrillReal-v0"):
        with pytest.raises(gym.error.DeprecatedEnv, match="-v1"), pytest.warns(DeprecationWarning):
            gym.make(old)
