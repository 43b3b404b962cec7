"""The Net F/T's web server, as far as clients read it: ``GET /netftapi2.xml`` (its settings and calibration as XML).

ATI's Net F/T serves its settings at ``http://SENSOR/netftapi2.xml`` (``?index=N``: configuration N of 16; ATI
manual 9620-05-NET FT, the web pages and their XML form). RDT records hold counts only, so clients read the counts
per force and torque (``cfgcpf``, ``cfgcpt``) and their units (``scfgfu``, ``scfgtu``) there before they stream:
pyNetFT's native core requests ``/netftapi2.xml`` and parses those four fields and ``prodname`` (pyNetFT 2.1.3,
``Config(http_port=80)`` by default), ATI's Java sample reads ``netftapi2.xml?index=N``. The fields served here, named
and spelled as on a sensor's page (a Gamma's, firmware 2.2.59, as a public test fixture quotes it: ``N``, ``Nm``):

``prodname``, ``runstat`` (0x00000000: no error), ``runrate`` (internal rate, Hz), ``setcfgsel`` (active
configuration), ``setuserfilter``, ``cfgnam``, ``cfgcalsel``, ``cfgcalsn``, ``cfgfu`` / ``scfgfu`` (2, N),
``cfgtu`` / ``scfgtu`` (3, Nm), ``cfgcpf`` (counts per N), ``cfgcpt`` (counts per N·m), ``cfgtfx`` (tool transform,
0), ``comrdte``, ``comrdtrate`` (the RDT output rate, Hz), ``comrdtbsiz`` (records per buffered RDT packet), ``netip``.

The emulated sensor has one configuration, the active one (0); ``?index=N`` for any N in 0-15 shows it. HTTP/1.1,
one request per connection (``Connection: close``); ``GET`` and ``HEAD``; another path is 404, another method 405, a
request line that is not HTTP 400, a request head over :data:`MAX_REQUEST_BYTES` 431.
"""

from __future__ import annotations

import re
from typing import TYPE_CHECKING
from urllib.parse import parse_qs, urlsplit

if TYPE_CHECKING:
    from drillgym.envs.real.emulator.config import EmulatorConfig
    from drillgym.envs.real.emulator.nonblocking import StreamClient

MAX_REQUEST_BYTES = 8192
"""Longest request head read (bytes); a longer one is answered 431 and the connection closed."""
CONFIGURATIONS = 16
"""Configuration slots of a Net F/T (``index`` 0-15)."""
INTERNAL_RATE_HZ = 7000
REQUEST_LINE_RE = re.compile(r"^([A-Z]+) (\S+) HTTP/1\.[01]$")


def netftapi2_xml(config: EmulatorConfig) -> str:
    """The emulated sensor's ``netftapi2.xml``: calibration, units and RDT settings of ``config``."""
    cal = config.calibration
    fields = {
        "prodname": "ATI Net F/T (drillgym emulator)",
        "runstat": "0x00000000",
        "runrate": str(INTERNAL_RATE_HZ),
        "setcfgsel": "0",
        "setuserfilter": "0",
        "cfgnam": "drillgym",
        "cfgcalsel": "0",
        "cfgcalsn": "EMU0001",
        "cfgfu": "2",
        "scfgfu": "N",
        "cfgtu": "3",
        "scfgtu": "Nm",
        "cfgcpf": str(round(cal.counts_per_force)),
        "cfgcpt": str(round(cal.counts_per_torque)),
        "cfgtfx": "0;0;0;0;0;0",
        "scfgtdu": "mm",
        "scfgtau": "degrees",
        "comrdte": "Enabled",
        "comrdtrate": str(round(config.ft_rate_hz)),
        "comrdtbsiz": str(config.ft_rdt_buffer_size),
        "netip": config.host,
    }
    body = "".join(f"<{k}>{v}</{k}>" for k, v in fields.items())
    return f'<?xml version="1.0" encoding="utf-8"?>\n<netft>{body}</netft>\n'


def serve_http(client: StreamClient, config: EmulatorConfig) -> None:
    """Answer a web client once its request head has arrived (queued on its outbox; the client then closes)."""
    head_end = client.inbox.find(b"\r\n\r\n")
    if head_end < 0:
        head_end = client.inbox.find(b"\n\n")
    if head_end < 0:
        if len(client.inbox) > MAX_REQUEST_BYTES:
            client.outbox.queue(_response(431, "Request Header Fields Too Large", "request head too long\n"))
            client.closing = True
        return
    request_line = bytes(client.inbox[: client.inbox.find(b"\n")]).decode("latin-1").strip()
    client.inbox.clear()
    client.closing = True
    client.outbox.queue(answer(request_line, config))
    client.log(f"{request_line[:120]!r} answered")


def answer(request_line: str, config: EmulatorConfig) -> bytes:
    """The whole HTTP response to one request line (``GET /netftapi2.xml?index=0 HTTP/1.1``)."""
    m = REQUEST_LINE_RE.match(request_line)
    if m is None:
        return _response(400, "Bad Request", "not an HTTP/1.x request line\n")
    method, target = m.groups()
    if method not in ("GET", "HEAD"):
        return _response(405, "Method Not Allowed", f"{method} not allowed\n", extra="Allow: GET, HEAD\r\n")
    url = urlsplit(target)
    if url.path != "/netftapi2.xml":
        return _response(404, "Not Found", f"{url.path} not found (the emulator serves /netftapi2.xml)\n")
    index = parse_qs(url.query).get("index", ["0"])[0]
    if not (index.isdigit() and int(index) < CONFIGURATIONS):
        return _response(400, "Bad Request", f"index={index[:20]} is not a configuration 0-{CONFIGURATIONS - 1}\n")
    return _response(200, "OK", netftapi2_xml(config), content_type="text/xml", head_only=method == "HEAD")


def _response(
    code: int, reason: str, body: str, content_type: str = "text/plain", extra: str = "", head_only: bool = False
) -> bytes:
    data = body.encode()
    head = (
        f"HTTP/1.1 {code} {reason}\r\nContent-Type: {content_type}\r\nContent-Length: {len(data)}\r\n"
        f"Connection: close\r\n{extra}\r\n"
    )
    return head.encode() + (b"" if head_only else data)
