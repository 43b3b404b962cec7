"""``python -m envs.real.emulator``: the same as ``drillgym emulate``."""

import argparse
import sys

from envs.real.emulator import cli

parser = argparse.ArgumentParser(prog="python -m envs.real.emulator", description=cli.__doc__)
cli.add_arguments(parser)
sys.exit(cli.run(parser.parse_args()))
