"""``python -m drillgym.envs.real.emulator``: the same as ``drillgym emulate``.

Once the emulator has closed its sockets and flushed its output it ends at once (``os._exit``): the interpreter's
teardown of the physics and compiled-kernel modules took another 0.3 s per emulator, which tests and benchmarks
that start one per case pay many times.
"""

import argparse
import os
import sys

from drillgym.envs.real.emulator import cli

parser = argparse.ArgumentParser(prog="python -m drillgym.envs.real.emulator", description=cli.__doc__)
cli.add_arguments(parser)
code = cli.run(parser.parse_args())
sys.stdout.flush()
sys.stderr.flush()
os._exit(code)
