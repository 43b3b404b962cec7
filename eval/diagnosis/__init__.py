"""Sim-to-real gap diagnosis: where the gap lies, which unmodelled effect explains it, how far it shrinks.

``diagnose(load_episodes(DIR)[0])`` returns the ``diagnosis.json`` dict; ``docs/diagnosis.md`` explains
the method. The reality generator is :mod:`drillgym.eval.diagnosis.reality`, the benchmark
:mod:`drillgym.eval.diagnosis.bench`, the candidate effects :mod:`drillgym.envs.effects`.
"""

from drillgym.eval.diagnosis.diagnose import DiagnoseOptions, Diagnosis, diagnose, run_diagnosis
from drillgym.eval.diagnosis.episodes import EpisodeData, episode_from_log, load_episodes
from drillgym.eval.diagnosis.rtde_import import import_session
from drillgym.eval.diagnosis.validate import LogCheckError, check_log

__all__ = [
    "DiagnoseOptions",
    "Diagnosis",
    "EpisodeData",
    "LogCheckError",
    "check_log",
    "diagnose",
    "episode_from_log",
    "import_session",
    "load_episodes",
    "run_diagnosis",
]
