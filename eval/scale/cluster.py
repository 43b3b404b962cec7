"""Connecting to Ray: a fresh local instance by default, an existing cluster with an address."""

from __future__ import annotations

import importlib.util
import logging
import os
import socket
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass

INSTALL_HINT = "Ray is not installed; install it with: pip install 'drillgym[ray]'"


def require_ray() -> None:
    """Raise ``ModuleNotFoundError`` with the install command when Ray is not importable."""
    if importlib.util.find_spec("ray") is None:
        raise ModuleNotFoundError(INSTALL_HINT, name="ray")


@dataclass(frozen=True)
class RaySession:
    """The Ray instance a command runs on."""

    address: str
    """``"local"`` for an instance started by this process, else the cluster address."""
    cpus: int
    """CPUs of the whole cluster when connected (Ray's ``CPU`` resource)."""
    nodes: int
    """Alive nodes when connected."""
    startup_s: float
    """Wall time of ``ray.init`` (s); 0 when Ray was already initialised in this process."""
    owned: bool
    """True when this process called ``ray.init`` and so calls ``ray.shutdown`` at the end."""

    def describe(self) -> str:
        """One line for the console."""
        where = "local Ray" if self.address == "local" else f"Ray cluster {self.address}"
        return f"{where}: {self.nodes} node(s), {self.cpus} CPUs, started/connected in {self.startup_s:.1f} s"


def _check_reachable(address: str, timeout_s: float = 5.0) -> None:
    """Fail fast on a ``HOST:PORT`` nobody listens on (Ray itself retries for minutes)."""
    host, sep, port = address.rpartition(":")
    if not sep or "://" in address or not port.isdigit():
        return  # "auto", "ray://...": left to Ray
    try:
        socket.create_connection((host, int(port)), timeout=timeout_s).close()
    except OSError as e:
        raise ConnectionError(f"cannot connect to the Ray cluster at {address!r}: {e}") from e


@contextmanager
def ray_session(address: str | None = None, num_cpus: int | None = None) -> Iterator[RaySession]:
    """Connect to Ray for the duration of a ``with`` block.

    Args:
        address: ``None`` starts a new local instance (never joins a cluster by accident); ``"auto"``
            joins the cluster started on this machine by ``ray start``; ``"HOST:6379"`` a cluster's head;
            ``"ray://HOST:10001"`` goes through Ray Client.
        num_cpus: CPUs of a local instance (default: every CPU of the machine); ignored for a cluster.

    Raises:
        ConnectionError: no Ray cluster answers at ``address``.

    Yields:
        The session. An instance that was already initialised in this process (tests, notebooks) is
        reused and left running.
    """
    require_ray()
    import ray

    t0 = time.perf_counter()
    if address not in (None, "auto") and not str(address).startswith("ray://"):
        _check_reachable(str(address))  # also when an instance is already up: never run elsewhere silently
    owned = not ray.is_initialized()
    if owned:
        if address is None:
            ray.init(
                address="local",
                num_cpus=num_cpus or os.cpu_count() or 1,
                include_dashboard=False,
                logging_level=logging.WARNING,
            )
        else:
            _check_reachable(address)
            try:
                ray.init(address=address, logging_level=logging.WARNING)
            except (ConnectionError, RuntimeError) as e:
                raise ConnectionError(f"cannot connect to the Ray cluster at {address!r}: {e}") from e
    startup_s = time.perf_counter() - t0 if owned else 0.0
    nodes = sum(1 for n in ray.nodes() if n.get("Alive"))
    cpus = int(ray.cluster_resources().get("CPU", 0))
    try:
        yield RaySession(address or "local", cpus, nodes, startup_s, owned)
    finally:
        if owned:
            ray.shutdown()
