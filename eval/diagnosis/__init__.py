"""Sim-to-real gap diagnosis: where the gap lies, which unmodelled effect explains it, how far it shrinks.

``diagnose(load_episodes(DIR)[0])`` returns the ``diagnosis.json`` dict; ``docs/diagnosis.md`` explains
the method. The reality generator is :mod:`eval.diagnosis.reality`, the benchmark
:mod:`eval.diagnosis.bench`, the candidate effects :mod:`envs.effects`.
"""

from eval.diagnosis.diagnose import DiagnoseOptions, Diagnosis, diagnose, run_diagnosis
from eval.diagnosis.episodes import EpisodeData, episode_from_log, load_episodes
from eval.diagnosis.rtde_import import import_session
from eval.diagnosis.validate import LogCheckError, check_log

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
