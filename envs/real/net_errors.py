"""Socket errors that say where and what to check: ``HOST:PORT`` and a hint, on one line.

A bare ``[Errno 98] Address already in use`` or ``[Errno 111] Connection refused`` names neither the address
nor the port nor what to do. :func:`bind_error` (a server that cannot listen: the emulator) and
:func:`connect_error` (a client that cannot reach a device: the F/T sensor) return an ``OSError`` of the same
class and errno whose message does; the ``drillgym`` front prints it as ``drillgym CMD: error: ...``.
"""

from __future__ import annotations

import errno
import socket


def _reason(error: OSError) -> str:
    if isinstance(error, TimeoutError):
        return "no answer (timed out)"
    return error.strerror or str(error) or type(error).__name__


def _same_kind(error: OSError, message: str) -> OSError:
    """An ``OSError`` of ``error``'s class and errno with ``message`` as its text."""
    try:
        new = type(error)(message)
    except TypeError:  # pragma: no cover - an OSError subclass with another constructor
        new = OSError(message)
    new.errno = error.errno
    return new


def bind_error(error: OSError, host: str, port: int, what: str, option: str | None = None) -> OSError:
    """Why ``what`` (e.g. ``"RTDE (TCP)"``) could not listen on ``host:port``, and what to do about it.

    ``option`` names the command-line option that moves this port (e.g. ``"--rtde-port"``).
    """
    other_port = f" (or move this port with {option})" if option else ""
    if error.errno == errno.EADDRINUSE:
        hint = (
            f"is another emulator or URSim running on {host}? choose another --host 127.0.0.X{other_port}, "
            f"or find the process with: ss -ltnup | grep ':{port} '"
        )
    elif error.errno == errno.EADDRNOTAVAIL:
        hint = f"{host} is not an address of this machine: serve on a loopback address, --host 127.0.0.X"
    elif error.errno == errno.EACCES:
        hint = f"ports below 1024 need root{other_port or '; choose a higher port'}"
    elif isinstance(error, socket.gaierror):
        hint = "not an IP address: give --host as 127.0.0.X"
    else:
        hint = f"check --host{other_port}"
    return _same_kind(error, f"cannot serve {what} on {host}:{port}: {_reason(error)}; {hint}")


def connect_error(error: OSError, host: str, port: int, what: str) -> OSError:
    """Why ``what`` (e.g. ``"the F/T sensor's calibration (TCP)"``) could not be reached at ``host:port``."""
    if isinstance(error, socket.gaierror):
        hint = f"{host} is not a known host name: give the sensor's IP address"
    elif error.errno == errno.ECONNREFUSED:
        hint = f"is the sensor at {host} powered and reachable? check the address with ping {host}"
        if host.startswith("127."):
            hint += f"; on loopback, is the emulator running? drillgym emulate --host {host}"
    else:  # timed out, host or network unreachable
        hint = (
            f"is the sensor at {host} powered and on this PC's network? check the address with ping {host} "
            "and the PC's address on the sensor's subnet"
        )
    return _same_kind(error, f"cannot reach {what} at {host}:{port}: {_reason(error)}; {hint}")
