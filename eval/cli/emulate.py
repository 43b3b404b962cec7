"""``drillgym emulate``: serve a UR CB3 controller + ATI Net F/T emulator, backed by the simulator.

The emulator and its options live with it (:mod:`drillgym.envs.real.emulator.cli`), so that
``python -m drillgym.envs.real.emulator`` serves it without the rest of drillgym; this command is the same.
"""

from drillgym.envs.real.emulator.cli import add_arguments, run

__all__ = ["add_arguments", "run"]
