"""Ray is optional: the env, the controllers, the local bench and a training run never import it."""

import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def test_core_modules_and_a_local_bench_do_not_import_ray(tmp_path):
    code = f"""
import sys
import drillgym.envs, drillgym.controllers, drillgym.eval.cli.bench, drillgym.eval.bench.episode, drillgym.eval.cli
import drillgym.training.train, drillgym.training.sweep
from drillgym.eval.cli import main
assert main(["bench", "--controllers", "none", "--seeds", "1", "--no-logs", "--out", {str(tmp_path / "b")!r}]) == 0
drillgym.training.sweep.load_sweep({str(ROOT / "training/sweeps/small.yaml")!r})
loaded = sorted(m for m in sys.modules if m == "ray" or m.startswith("ray."))
assert not loaded, loaded
print("no ray")
"""
    proc = subprocess.run([sys.executable, "-c", code], cwd=ROOT, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "no ray" in proc.stdout
