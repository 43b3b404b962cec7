"""Emulated holes beside busy processes: does ``drillgym run`` finish them, and does its console explain each stop?

``python -m drillgym.eval.perf.loaded_runs --runs 20 --busy 2 --out results/loaded_runs`` starts ``--busy``
processes that spin on the CPU, then, one after the other, ``--runs`` fresh emulators (specimen seed = run
index) each drilled once by ``drillgym run --controller CONTROLLER --yes`` in a process of its own, as a user
runs it. Each run's console is kept (``<out>/run_<i>.txt``) and ``<out>/summary.json`` says, per run, its exit
code, its fault (from the run's ``metrics.json``) and whether the console explains it: a stop is *explained*
when the console names the fault and prints the servo-timing line and a ``likely cause`` line
(:mod:`drillgym.eval.real.load_report`; for a stop other than a stale stream or the
watchdog, the fault line suffices). The output folder must not exist (a record is never overwritten).
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import os
import subprocess
import sys
import time
from pathlib import Path
from typing import Any

from drillgym.envs.json_safe import json_safe
from drillgym.envs.real.emulator.process import EmulatorProcess
from drillgym.eval.real.load_report import LOAD_FAULTS


def _spin(stop: Any) -> None:
    """A busy process: arithmetic until ``stop`` is set (checked every few ms)."""
    x = 0
    while not stop.is_set():
        for i in range(50_000):
            x = (x + i * i) % 1_000_003


def _explained(console: str, failure: str | None) -> bool:
    """Whether the console explains ``failure``.

    It does when it names the fault and prints the servo timing, and, for a stop a busy machine can cause
    (:data:`~drillgym.eval.real.load_report.LOAD_FAULTS`), a likely cause.
    """
    if failure is None:
        return True
    named = f"ENDED ON A FAULT: {failure}" in console and "servo loop:" in console
    return named and ("likely cause:" in console or failure not in LOAD_FAULTS)


def one_run(i: int, controller: str, out: Path) -> dict[str, Any]:
    """Drill one hole on a fresh emulator (specimen seed ``i``); the run's record goes to ``out/run_<i>``."""
    run_out = out / f"run_{i}"
    with EmulatorProcess(seed=i, max_lifetime_s=300.0) as emu:
        t0 = time.monotonic()
        cmd = [sys.executable, "-m", "drillgym.eval.cli", "run", "--robot", emu.host, "--tracker", f"udp:{emu.host}"]
        cmd += ["--controller", controller, "--seed", str(i), "--yes", "--out", str(run_out)]
        done = subprocess.run(cmd, capture_output=True, text=True, timeout=600)
        wall_s = time.monotonic() - t0
    console = done.stdout + done.stderr
    (out / f"run_{i}.txt").write_text(console)
    metrics_path = run_out / "metrics.json"
    entries = json.loads(metrics_path.read_text()) if metrics_path.is_file() else []
    entry = entries[0] if isinstance(entries, list) and entries else {}
    failure = entry.get("failure") if isinstance(entry, dict) else None
    return {
        "run": i,
        "exit_code": done.returncode,
        "finished": done.returncode == 0 and failure is None,
        "failure": failure,
        "explained": _explained(console, failure),
        "missed_cycles": entry.get("missed_cycles") if isinstance(entry, dict) else None,
        "wall_s": wall_s,
    }


def main(argv: list[str] | None = None) -> int:
    """Run the benchmark; prints one line per run and the totals. Exit 0 when it ran (whatever it found)."""
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--runs", type=int, default=20, help="emulated holes, one after the other (default: 20)")
    p.add_argument("--busy", type=int, default=2, help="processes spinning on the CPU meanwhile (default: 2)")
    p.add_argument("--controller", default="residual:shipped", help="controller spec (default: residual:shipped)")
    p.add_argument("--out", type=Path, required=True, help="output folder (must not exist)")
    args = p.parse_args(argv)
    if args.runs < 1 or args.busy < 0:
        p.error(f"--runs must be >= 1 and --busy >= 0 (got {args.runs}, {args.busy})")
    if args.out.exists():
        p.error(f"{args.out} exists: a record is never overwritten; name a new --out")
    args.out.mkdir(parents=True)
    stop = mp.Event()
    busy = [mp.Process(target=_spin, args=(stop,), daemon=True) for _ in range(args.busy)]
    for b in busy:
        b.start()
    rows: list[dict[str, Any]] = []
    try:
        for i in range(args.runs):
            rows.append(one_run(i, args.controller, args.out))
            r = rows[-1]
            load = os.getloadavg()[0]
            print(
                f"run {i}: exit {r['exit_code']}, fault {r['failure']}, explained {r['explained']}, "
                f"missed cycles {r['missed_cycles']}, load {load:.1f}, {r['wall_s']:.1f} s",
                flush=True,
            )
            (args.out / "summary.json").write_text(json.dumps(json_safe({"busy": args.busy, "runs": rows}), indent=2))
    finally:
        stop.set()
        for b in busy:
            b.join(timeout=5)
    finished = sum(r["finished"] for r in rows)
    explained = sum(r["explained"] for r in rows if r["failure"] is not None)
    stopped = sum(r["failure"] is not None for r in rows)
    print(
        f"{finished}/{len(rows)} holes finished beside {args.busy} busy processes; "
        f"{explained}/{stopped} stops explained on the console; {args.out / 'summary.json'}"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
