"""``python -m drillgym.envs.real.emulator``: the same as ``drillgym emulate``."""

import argparse
import sys

from drillgym.envs.real.emulator import cli

parser = argparse.ArgumentParser(prog="python -m drillgym.envs.real.emulator", description=cli.__doc__)
cli.add_arguments(parser)
sys.exit(cli.run(parser.parse_args()))
