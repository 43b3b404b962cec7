"""Start, talk to and stop an emulator process (for tests, ``drillgym bench-rtde`` and scripts).

The emulator must run in its own process: ``ur_rtde``'s constructors block in a socket read while holding
the GIL, so an emulator thread in the client's process never gets to answer. The process is ended by its
own pid (shutdown request, then SIGTERM, then SIGKILL), and it exits by itself when its parent goes away.
"""

from __future__ import annotations

import json
import os
import random
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path
from typing import Any

from drillgym.envs.real.emulator.config import (
    CONTROL_PORT,
    DASHBOARD_PORT,
    FT_HTTP_PORT,
    PRIMARY_PORT,
    RTDE_PORT,
    SCRIPT_PORT,
    SECONDARY_PORT,
)
from drillgym.envs.real.netft import RDT_PORT
from drillgym.envs.real.netft_calibration import CAL_PORT
from drillgym.envs.real.tracker import TRACKER_PORT

TCP_PORTS = (RTDE_PORT, DASHBOARD_PORT, SCRIPT_PORT, PRIMARY_PORT, SECONDARY_PORT, CONTROL_PORT, CAL_PORT, FT_HTTP_PORT)
UDP_PORTS = (RDT_PORT, TRACKER_PORT)


def ports_free(host: str) -> bool:
    """Whether every emulator port can be bound on ``host`` (nothing else serves there)."""
    for kind, ports in ((socket.SOCK_STREAM, TCP_PORTS), (socket.SOCK_DGRAM, UDP_PORTS)):
        for port in ports:
            with socket.socket(socket.AF_INET, kind) as s:
                s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
                try:
                    s.bind((host, port))
                except OSError:
                    return False
    return True


def free_loopback_host(rng: random.Random | None = None, attempts: int = 50) -> str:
    """A random 127.x.y.z address (x in 100..199) whose emulator ports are all free."""
    r = rng or random.Random()
    for _ in range(attempts):
        host = f"127.{r.randint(100, 199)}.{r.randint(0, 255)}.{r.randint(1, 254)}"
        if ports_free(host):
            return host
    raise RuntimeError(f"no loopback address with free emulator ports after {attempts} tries")


def emulator_control(
    host: str, request: dict[str, Any], port: int = CONTROL_PORT, timeout_s: float = 5.0
) -> dict[str, Any]:
    """One request on an emulator's control port (JSON line in, JSON line out).

    Raises ``OSError`` when nothing answers there (a real controller has no such port) and ``RuntimeError``
    when the emulator refuses the request.
    """
    with socket.create_connection((host, port), timeout=timeout_s) as s:
        s.sendall((json.dumps(request) + "\n").encode())
        buf = b""
        while not buf.endswith(b"\n"):
            chunk = s.recv(1 << 20)
            if not chunk:
                break
            buf += chunk
    try:
        reply = json.loads(buf)
    except ValueError as e:
        raise OSError(f"{host}:{port} answered something other than the emulator's control protocol") from e
    if not isinstance(reply, dict) or not reply.get("ok"):
        raise RuntimeError(f"emulator control {request}: {reply.get('error') if isinstance(reply, dict) else reply}")
    return dict(reply)


class EmulatorProcess:
    """An emulator in a child process on ``host``; use as a context manager.

    Args:
        host: loopback address (default: a random free one).
        scenario: physical cell, env keyword arguments (user units).
        seed: specimen seed.
        extra_args: more ``drillgym emulate`` options (e.g. ``["--fault", "stale_ft@2"]``).
        log_path: the emulator's log (stderr); default a temporary file.
        max_lifetime_s: the emulator exits by itself after this long.
    """

    def __init__(
        self,
        host: str | None = None,
        scenario: dict[str, Any] | None = None,
        seed: int = 0,
        extra_args: list[str] | None = None,
        log_path: str | Path | None = None,
        max_lifetime_s: float = 600.0,
    ) -> None:
        self.host = host or free_loopback_host()
        self.scenario = dict(scenario or {})
        self.seed = seed
        self.extra_args = list(extra_args or [])
        self.max_lifetime_s = max_lifetime_s
        self._tmp = None if log_path else tempfile.NamedTemporaryFile(prefix="drillgym-emulator-", suffix=".log")
        self.log_path = Path(log_path) if log_path else Path(self._tmp.name)  # type: ignore[union-attr]
        self.proc: subprocess.Popen[str] | None = None
        self.info: dict[str, Any] = {}

    def start(self, timeout_s: float = 30.0) -> EmulatorProcess:
        """Spawn the process and wait for its READY line."""
        cmd = [
            sys.executable,
            "-m",
            "drillgym.envs.real.emulator",
            "--host",
            self.host,
            "--seed",
            str(self.seed),
            "--max-lifetime-s",
            str(self.max_lifetime_s),
            "--parent-pid",
            str(os.getpid()),
            *self.extra_args,
        ]
        if self.scenario:
            cmd += ["--scenario", json.dumps(self.scenario)]
        log = open(self.log_path, "w")
        try:
            self.proc = subprocess.Popen(cmd, stdout=subprocess.PIPE, stderr=log, text=True, cwd=_repo_root())
        finally:
            log.close()
        assert self.proc.stdout is not None
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            line = self.proc.stdout.readline()
            if line.startswith("READY "):
                self.info = json.loads(line[6:])
                return self
            if not line and self.proc.poll() is not None:
                break
        self.stop()
        raise RuntimeError(f"emulator on {self.host} did not start: {self.log_tail()}")

    def control(self, request: dict[str, Any], timeout_s: float = 5.0) -> dict[str, Any]:
        """Send one control request and return the reply (raises ``RuntimeError`` if not ok)."""
        return emulator_control(self.host, request, timeout_s=timeout_s)

    def fault(self, kind: str, value: float = 0.0) -> None:
        """Inject a fault now."""
        self.control({"cmd": "fault", "kind": kind, "value": value})

    def status(self) -> dict[str, Any]:
        """The emulator's status."""
        return self.control({"cmd": "status"})

    def log_tail(self, n_chars: int = 2000) -> str:
        """The end of the emulator's log."""
        try:
            return self.log_path.read_text()[-n_chars:]
        except OSError:
            return "(no log)"

    def stop(self, timeout_s: float = 5.0) -> int | None:
        """End the process by its pid: shutdown request, then SIGTERM, then SIGKILL. Returns its exit code."""
        proc = self.proc
        if proc is None:
            return None
        if proc.poll() is None:
            try:
                self.control({"cmd": "shutdown"}, timeout_s=1.0)
            except (OSError, RuntimeError, ValueError):
                pass
            try:
                proc.wait(timeout=timeout_s)
            except subprocess.TimeoutExpired:
                proc.terminate()
                try:
                    proc.wait(timeout=timeout_s)
                except subprocess.TimeoutExpired:
                    proc.kill()
                    proc.wait(timeout=timeout_s)
        if proc.stdout is not None:
            proc.stdout.close()
        if self._tmp is not None:
            self._tmp.close()
            self._tmp = None
        return proc.returncode

    def __enter__(self) -> EmulatorProcess:
        return self.start() if self.proc is None else self

    def __exit__(self, *exc: object) -> None:
        self.stop()


def _repo_root() -> str:
    return str(Path(__file__).resolve().parents[3])
