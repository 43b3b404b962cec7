"""A UR CB3 controller emulator backed by the drilling simulator, for testing the real-cell backend.

It speaks the real protocols on loopback — RTDE (30004), dashboard (29999), the script port (30003), the
ATI Net F/T RDT stream (UDP 49152) — well enough for the unmodified ``ur_rtde`` 1.6.5 client, plus a marker
stream and a JSON control port for fault injection. Start it with ``drillgym emulate`` or
:class:`drillgym.envs.real.emulator.process.EmulatorProcess` (always in its own process).
"""
