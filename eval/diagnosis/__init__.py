"""Sim-to-real gap diagnosis: where the gap lies, which unmodelled effect explains it, how far it shrinks.

``diagnose(load_episodes(DIR)[0])`` returns the ``diagnosis.json`` dict; ``docs/diagnosis.md`` explains
the method. The modules, in pipeline order:

1. **Load**: :mod:`.validate` (checks of a log, clear errors or documented repairs), :mod:`.rtde_import`
   (a ``ur_rtde`` recording session into episode logs), :mod:`.episodes` (commands, channels, stages).
2. **Label**: :mod:`.channels` (what is compared, and its scales), :mod:`.stages` (the drilling stage of
   every sample, from the commanded depth).
3. **Replay**: :mod:`.replay` (the simulator's answer to the logged commands), :mod:`.pool` (on every core).
4. **Compare**: :mod:`.features` (block means, HF power per stage), :mod:`.gap` (the gap in units of the
   simulator's own scatter), :mod:`.spectrum` (the gap over frequency), :mod:`.context` (what every
   process shares, and the misfit of a set of effects).
5. **Explain**: :mod:`.fit` (each candidate's parameters on calibration episodes, scored on held-out
   ones), :mod:`.rank` (scores, the parameter penalty, the naming bar, where the gap lies), :mod:`.pairs` (the
   pair rule and the guards on what an effect predicts where it alone acts), :mod:`.intervals` (parameter
   intervals), :mod:`.verdict` (the verdict and its summary line).
6. **Report**: :mod:`.report`, :mod:`.figures`; :mod:`.diagnose` runs 1–6.

The candidate effects are :mod:`drillgym.envs.effects`; the reality generator (effects the diagnosing
simulator is not told about) is :mod:`.reality`, the withheld-effect benchmark :mod:`.bench`.
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
