"""The UR controller emulator's event loop: one thread, one ``selectors`` loop, fixed-rate ticks.

Serves RTDE (30004), the dashboard (29999), the script ports (30003, and 30001 / 30002, which take URScript
too; with their client state streams, :mod:`~drillgym.envs.real.emulator.state_streams`), the ATI Net F/T RDT
stream (UDP 49152) and web page (HTTP, :mod:`~drillgym.envs.real.emulator.netft_http`), a marker stream (UDP 49153)
and a JSON control port (30100, fault injection and truth) on one loopback address. Ticks: physics 100 Hz (the
simulator's F/T rate), controller 125 Hz (program cycle, RTDE output and the 30003 packet, as a CB3), F/T records
at ``ft_rate_hz``, marker records at ``tracker_rate_hz``.

No client can stall the loop or end the process: sockets are non-blocking, replies wait in bounded outboxes
(a client that does not read them is dropped and logged), reads are bounded per loop turn
(:mod:`~drillgym.envs.real.emulator.nonblocking`), and an exception while handling one client's input is logged
with its traceback and closes that client only.
"""

from __future__ import annotations

import json
import os
import selectors
import socket
import struct
import sys
import time
import traceback
from collections.abc import Callable

from drillgym.envs.constants import PHYSICS_DT_S
from drillgym.envs.real.emulator.config import EmulatorConfig
from drillgym.envs.real.emulator.control import handle_control
from drillgym.envs.real.emulator.dashboard import WELCOME, Dashboard
from drillgym.envs.real.emulator.faults import FaultState
from drillgym.envs.real.emulator.netft_http import serve_http
from drillgym.envs.real.emulator.nonblocking import (
    LINE_TURN_BUDGET_S,
    MAX_LINE_BYTES,
    MAX_SCRIPT_BYTES,
    READ_CHUNK_BYTES,
    SCRIPT_CHUNK_BYTES,
    STREAM_OUTBOX_BYTES,
    LogBudget,
    Outbox,
    StreamClient,
)
from drillgym.envs.real.emulator.registers import Registers
from drillgym.envs.real.emulator.rtde_server import CB3_RATE_HZ, RtdeConnection
from drillgym.envs.real.emulator.script import ControlProgram
from drillgym.envs.real.emulator.script_framing import split_programs
from drillgym.envs.real.emulator.sensor_streams import SensorStreams
from drillgym.envs.real.emulator.state import controller_state
from drillgym.envs.real.emulator.state_streams import StateStreams
from drillgym.envs.real.emulator.world import EmulatedCell
from drillgym.envs.real.net_errors import bind_error
from drillgym.envs.real.netft_calibration import CAL_REQUEST, CMD_READCALINFO, pack_calinfo

CONTROLLER_DT_S = 1.0 / CB3_RATE_HZ
ROBOT_PORTS = ("rtde", "dashboard", "script", "primary", "secondary")
SCRIPT_KINDS = ("script", "primary", "secondary")
UNLOCK_WAIT_S = 5.0
"""A protective stop cannot be unlocked sooner than this after it occurred (UR Dashboard Server manual)."""
"""Listeners that a dropped link takes down (the control port stays up)."""
PORT_NAMES = {
    "rtde": ("RTDE (TCP)", "--rtde-port"),
    "dashboard": ("the dashboard (TCP)", "--dashboard-port"),
    "script": ("the script port (TCP)", "--script-port"),
    "primary": ("the primary interface (TCP)", "--primary-port"),
    "secondary": ("the secondary interface (TCP)", "--secondary-port"),
    "control": ("the control port (TCP)", "--control-port"),
    "ft_cal": ("the Net F/T calibration port (TCP)", "--ft-cal-port"),
    "ft_http": ("the Net F/T web page (HTTP)", "--ft-http-port"),
    "ft": ("the Net F/T RDT stream (UDP)", "--ft-port"),
    "tracker": ("the marker stream (UDP)", "--tracker-port"),
}
"""Each listener's name in an error message and the option that moves its port."""


class Emulator:
    """One emulated cell on ``config.host``."""

    def __init__(self, config: EmulatorConfig) -> None:
        self.config = config
        self.sel = selectors.DefaultSelector()
        self.regs = Registers()
        self.world = EmulatedCell(config.scenario, config.seed, ft_rate_hz=config.ft_rate_hz)
        self.program = ControlProgram(self.regs, self.world)
        self.faults = FaultState(list(config.faults))
        self.dashboard = Dashboard(self.program, lambda: self.world.halted, self.unlock_protective_stop)
        self.sensors = SensorStreams(self.world, config, self._bind_udp, self.log)
        self.state_streams = StateStreams()
        self.listeners: dict[str, socket.socket] = {}
        self.rtde: list[RtdeConnection] = []
        self.streams: dict[socket.socket, StreamClient] = {}
        self.backlogged: set[socket.socket] = set()
        """Line clients whose received lines are not all answered yet (see :meth:`_read_lines`)."""
        self.log_budgets: dict[str, LogBudget] = {}
        """Each port's :class:`LogBudget`, shared by its clients."""
        self.owners: dict[str, int] = {}
        self.output_recipes: list[list[str]] = []
        self.input_recipes: list[list[list[str]]] = []
        self.next_conn_id = 1
        self.t0 = time.monotonic()
        self.controller_ticks = 0
        self.late_ticks = 0
        self.first_servo_t_s: float | None = None
        self.shutdown = False
        self.log_lines = 0
        self.next_phys = self.next_ctrl = self.next_check = 0.0

    # ------------------------------------------------------------------ utilities
    def now(self) -> float:
        """Emulator time (s since start)."""
        return time.monotonic() - self.t0

    def log(self, line: str) -> None:
        """One line to stderr (the process's log)."""
        self.log_lines += 1
        print(f"[{self.now():9.3f}] {line}", file=sys.stderr, flush=True)

    def _bind_udp(self, port: int, on_read: Callable[[socket.socket], None]) -> socket.socket:
        s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        name = "ft" if port == self.config.ft_port else "tracker"
        self._bind(s, name, port)
        s.setblocking(False)
        self.sel.register(s, selectors.EVENT_READ, on_read)
        return s

    def _bind(self, s: socket.socket, name: str, port: int) -> None:
        """Bind ``s`` to ``host:port``; an ``OSError`` that names them and says what to check (the socket closed)."""
        try:
            s.bind((self.config.host, port))
        except OSError as e:
            s.close()
            what, option = PORT_NAMES[name]
            raise bind_error(e, self.config.host, port, what, option) from e

    def _listen(self, name: str, port: int) -> None:
        s = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        s.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self._bind(s, name, port)
        s.listen(8)
        s.setblocking(False)
        self.listeners[name] = s
        self.sel.register(s, selectors.EVENT_READ, lambda sock, n=name: self._accept(n, sock))

    def open_robot_ports(self) -> None:
        """(Re)open the RTDE, dashboard and script listeners."""
        cfg = self.config
        robot_ports = (cfg.rtde_port, cfg.dashboard_port, cfg.script_port, cfg.primary_port, cfg.secondary_port)
        for name, port in zip(ROBOT_PORTS, robot_ports, strict=True):
            if name not in self.listeners:
                self._listen(name, port)

    def drop_link(self) -> None:
        """Cut every robot connection and stop listening (cable pulled); the control port stays up."""
        for name in ROBOT_PORTS:
            s = self.listeners.pop(name, None)
            if s is not None:
                self.sel.unregister(s)
                s.close()
        for conn in list(self.rtde):
            self._close_rtde(conn)
        for s in [s for s, client in self.streams.items() if client.kind in ROBOT_PORTS]:
            self._close_stream(s)
        self.log("link dropped: robot ports closed")

    def unlock_protective_stop(self, t_s: float, wait: bool = True) -> bool:
        """Release a protective stop (the program stays paused until played); whether it was released.

        As on a UR controller, an unlock within :data:`UNLOCK_WAIT_S` of the stop is refused (``wait=False``:
        the test harness clearing its own fault).
        """
        if wait and self.world.halted and t_s - self.world.halted_at_s < UNLOCK_WAIT_S:
            return False
        self.world.halted = False
        return True

    def _log_budget(self, port: str) -> LogBudget:
        """The log budget shared by every client of ``port`` (created on first use)."""
        if port not in self.log_budgets:
            self.log_budgets[port] = LogBudget(self.log)
        return self.log_budgets[port]

    # ------------------------------------------------------------------ sockets
    def _accept(self, name: str, listener: socket.socket) -> None:
        try:
            sock, _ = listener.accept()
        except OSError:
            return
        sock.setblocking(False)
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        if name == "rtde":
            conn = RtdeConnection(
                sock, self.regs, self.owners, self.next_conn_id, self.log, self.program.on_input, self._log_budget(name)
            )
            self.next_conn_id += 1
            self.rtde.append(conn)
            self.input_recipes.append(conn.input_recipe_log)
            self.sel.register(sock, selectors.EVENT_READ, lambda s, c=conn: self._read_rtde(c))
            return
        budget = self._log_budget(name)
        client = StreamClient(
            name, bytearray(), Outbox(sock, STREAM_OUTBOX_BYTES), lambda line: budget(f"{name}: {line}")
        )
        self.streams[sock] = client
        self.sel.register(sock, selectors.EVENT_READ, self._read_stream)
        if name == "dashboard":
            client.outbox.queue(WELCOME.encode())
        elif name in ("primary", "secondary"):
            client.outbox.queue(self.state_streams.greeting(self.now()))

    def _read_rtde(self, conn: RtdeConnection) -> None:
        try:
            data = conn.sock.recv(READ_CHUNK_BYTES["rtde"])
        except BlockingIOError:
            return
        except OSError:
            data = b""
        if not data:
            self._close_rtde(conn)
            return
        try:
            conn.receive(data, self.now())
        except ValueError:  # the framing is lost: the client was told, and is closed
            conn.flush(self.now())
            self._close_rtde(conn)
            return
        if conn.output_names and conn.output_names not in self.output_recipes:
            self.output_recipes.append(list(conn.output_names))

    def _close_rtde(self, conn: RtdeConnection) -> None:
        if conn in self.rtde:
            self.rtde.remove(conn)
            self.sel.unregister(conn.sock)
        conn.release()

    def _read_stream(self, sock: socket.socket) -> None:
        client = self.streams[sock]
        kind = client.kind
        if sock in self.backlogged:  # earlier lines still unanswered: leave the rest in the kernel for now
            return
        try:
            data = sock.recv(SCRIPT_CHUNK_BYTES if kind in SCRIPT_KINDS else READ_CHUNK_BYTES[kind])
        except BlockingIOError:
            return
        except OSError:
            data = b""
        if not data:
            if kind in SCRIPT_KINDS and client.inbox.strip():
                self.log(f"{kind} port: connection closed with {len(client.inbox)} bytes of an incomplete program")
            self._close_stream(sock)
            return
        if client.closing:  # input after quit / shutdown / a one-shot reply is not read
            return
        client.inbox.extend(data)
        if kind == "ft_cal":
            self._answer_ft_tcp(client)
        elif kind == "ft_http":
            serve_http(client, self.config)
        elif kind in SCRIPT_KINDS:
            self._read_script(client)
            if len(client.inbox) > MAX_SCRIPT_BYTES:
                self.log(f"{kind} port: more than {MAX_SCRIPT_BYTES} bytes of an incomplete program; closing")
                self._close_stream(sock)
        else:
            self._read_lines(sock, client)

    def _read_lines(self, sock: socket.socket, client: StreamClient) -> None:
        """Answer the complete lines of a dashboard or control client (replies queued, sent without waiting).

        At most :data:`LINE_TURN_BUDGET_S` of work per loop turn: lines left over make the client backlogged,
        answered on the next turns before anything more is read from it.
        """
        deadline = time.monotonic() + LINE_TURN_BUDGET_S
        self.backlogged.discard(sock)
        while not client.closing:
            end = client.inbox.find(b"\n")
            if end < 0:
                break
            if time.monotonic() > deadline:
                self.backlogged.add(sock)
                return
            line = client.inbox[:end].decode(errors="replace")
            del client.inbox[: end + 1]
            if client.kind == "dashboard":
                reply, client.closing = self.dashboard.reply(line, self.now())
                for note in self.dashboard.notes:
                    client.log(note)
                self.dashboard.notes.clear()
            else:
                reply_obj, client.closing = handle_control(self, line)
                reply = json.dumps(reply_obj)
            client.outbox.queue((reply + "\n").encode())
        if len(client.inbox) > MAX_LINE_BYTES and not client.closing:
            self.log(f"{client.kind}: a line of more than {MAX_LINE_BYTES} bytes without a newline; closing")
            self._close_stream(sock)

    def _read_script(self, client: StreamClient) -> None:
        """Run each program complete in the inbox (LF or CRLF, several per chunk: :func:`split_programs`)."""
        kind = client.kind
        port = {"script": self.config.script_port, "primary": self.config.primary_port}.get(
            kind, self.config.secondary_port
        )
        for text in split_programs(client.inbox):
            self.program.run_script(text, self.now(), port)
            client.log(f"port {port}: program of {len(text)} bytes received")

    def _answer_ft_tcp(self, client: StreamClient) -> None:
        """The Net F/T's TCP interface: ``READCALINFO`` answered with the configured calibration, nothing else."""
        buf = client.inbox
        if len(buf) < CAL_REQUEST.size:
            return
        if buf[0] == CMD_READCALINFO:
            client.outbox.queue(pack_calinfo(self.config.calibration))
        else:
            self.log(f"ft tcp: command {buf[0]} not emulated (only READCALINFO); closing")
        client.closing = True

    def _close_stream(self, sock: socket.socket) -> None:
        self.backlogged.discard(sock)
        if self.streams.pop(sock, None) is not None:
            self.sel.unregister(sock)
        sock.close()

    def _flush_streams(self) -> None:
        """Send the queued replies without waiting; drop (and log) a client that does not read them."""
        for sock, client in list(self.streams.items()):
            if not client.outbox.flush():
                unsent = len(client.outbox.pending)
                if unsent:
                    self.log(f"{client.kind}: client does not read its replies ({unsent} bytes unsent); dropped")
                self._close_stream(sock)
            elif client.closing and not client.outbox.pending:
                self._close_stream(sock)

    def _guarded(self, handler: Callable[[socket.socket], None], sock: socket.socket) -> None:
        """Run one socket's handler; an exception is logged with its traceback and closes that client only."""
        try:
            handler(sock)
        except Exception as e:
            where = next((f"rtde#{c.conn_id}" for c in self.rtde if c.sock is sock), None)
            if where is None and sock in self.streams:
                where = f"{self.streams[sock].kind} client"
            tb = traceback.format_exc().strip().splitlines()
            self.log(
                f"internal error handling {where or 'a listener'}: {type(e).__name__}: {e}; " + " | ".join(tb[-6:])
            )
            for conn in [c for c in self.rtde if c.sock is sock]:
                self._close_rtde(conn)
            if sock in self.streams:
                self._close_stream(sock)

    # ------------------------------------------------------------------ ticks
    def controller_tick(self, t_s: float) -> None:
        """One 8 ms controller cycle: faults, program, RTDE output."""
        if self.first_servo_t_s is None and self.program.servo_updates:
            self.first_servo_t_s = t_s
        self.faults.fire_scheduled(self, t_s)
        self.program.tick(t_s)
        self.controller_ticks += 1
        state = controller_state(self, t_s)
        release = t_s + self.faults.delay_s if self.faults.delay_s > 0 else None
        for conn in list(self.rtde):
            if conn.started and not self.faults.rtde_frozen(t_s) and self.controller_ticks % conn.divider == 0:
                try:
                    package = conn.data_package(state)
                except (ValueError, TypeError, OverflowError, struct.error) as e:
                    self.log(f"rtde#{conn.conn_id}: output package not packable ({e}); closing")
                    self._close_rtde(conn)
                    continue
                conn.send(package, release)
                conn.sent_packages += 1
        self.state_streams.tick(t_s, state, list(self.streams.values()))

    def run(self) -> int:
        """Serve until shutdown, SIGTERM, the parent's exit or the lifetime limit. Returns the exit code."""
        cfg = self.config
        try:
            self.open_robot_ports()
            self._listen("control", cfg.control_port)
            self._listen("ft_cal", cfg.ft_cal_port)
            self._listen("ft_http", cfg.ft_http_port)
            self.sensors.open()
        except OSError:  # a port in use: free the ones already bound, say which one
            self.close()
            raise
        ports = {
            "rtde": cfg.rtde_port,
            "dashboard": cfg.dashboard_port,
            "script": cfg.script_port,
            "primary": cfg.primary_port,
            "secondary": cfg.secondary_port,
            "control": cfg.control_port,
            "ft": cfg.ft_port,
            "ft_cal": cfg.ft_cal_port,
            "ft_http": cfg.ft_http_port,
            "tracker": cfg.tracker_port,
        }
        print("READY " + json.dumps({"host": cfg.host, "ports": ports, "pid": os.getpid()}), flush=True)
        print(  # for a person (stdout's READY line is for programs)
            f"UR CB3 emulator on {cfg.host} (RTDE {cfg.rtde_port}, dashboard {cfg.dashboard_port}, Net F/T "
            f"{cfg.ft_port}, tracker UDP {cfg.tracker_port}); exits after {cfg.max_lifetime_s:g} s or on Ctrl-C.\n"
            f"Drill a hole on it: drillgym run --robot {cfg.host} --tracker udp:{cfg.host} --out runs/emulated --yes",
            file=sys.stderr,
            flush=True,
        )
        self.next_phys = self.next_ctrl = self.next_check = self.now()
        while not self.shutdown:
            self._loop_once()
        self.close()
        return 0

    def _loop_once(self) -> None:
        """Wait for sockets or the next tick, then run what is due."""
        now = self.now()
        deadline = min(self.next_phys, self.next_ctrl, self.next_check, self.sensors.next_due_s())
        self._serve_clients(0.0 if self.backlogged else max(deadline - now, 0.0))
        now = self.now()
        if now >= self.next_phys:
            self.world.physics_tick(self.next_phys)
            self.next_phys += PHYSICS_DT_S
            if now - self.next_phys > 0.2:
                self.next_phys = now
        if now >= self.next_ctrl:
            if now - self.next_ctrl > CONTROLLER_DT_S:
                self.late_ticks += 1
            self.controller_tick(self.next_ctrl)
            self.next_ctrl += CONTROLLER_DT_S
            if now - self.next_ctrl > 0.2:
                self.next_ctrl = now
        self.sensors.tick(now, self.faults)
        for conn in list(self.rtde):
            if not conn.flush(now):
                self.log(f"rtde#{conn.conn_id}: send failed or backlog; closing")
                self._close_rtde(conn)
        self._flush_streams()
        if now >= self.next_check:
            self.next_check = now + 0.5
            self._housekeeping(now)

    def _serve_clients(self, timeout_s: float) -> None:
        """Handle the sockets that are ready within ``timeout_s`` (s), then the backlogged line clients' next lines."""
        for key, _ in self.sel.select(timeout_s):
            self._guarded(key.data, key.fileobj)  # type: ignore[arg-type]
        for sock in list(self.backlogged):
            self._guarded(lambda s: self._read_lines(s, self.streams[s]), sock)

    def _housekeeping(self, now: float) -> None:
        """Twice a second: faults that expire, the lifetime limit, the parent process."""
        cfg = self.config
        self.faults.expire(self, now)
        if now > cfg.max_lifetime_s:
            self.log(f"lifetime limit {cfg.max_lifetime_s} s reached; exiting")
            self.shutdown = True
        elif cfg.parent_pid is not None and os.getppid() != cfg.parent_pid:
            self.log(f"parent process {cfg.parent_pid} is gone; exiting")
            self.shutdown = True

    def close(self) -> None:
        """Close every socket (the replies already queued are sent first, without waiting)."""
        self._flush_streams()
        for conn in list(self.rtde):
            self._close_rtde(conn)
        for sock in list(self.streams):
            self._close_stream(sock)
        for s in self.listeners.values():
            s.close()
        self.listeners.clear()
        self.sensors.close()
        self.sel.close()
