"""Episode logs: one Parquet log per episode, written as it runs, readable after a crash.

``EpisodeLogger(env, "run.parquet", build_header(env, controller.describe()))`` logs an episode;
``read_episode_log("run.parquet")`` returns ``(header, DataFrame)``. Schema: ``docs/log_schema.md``.
"""

from drillgym.eval.logs.header import build_header, package_versions
from drillgym.eval.logs.logger import EpisodeLogger
from drillgym.eval.logs.reader import EpisodeLogError, read_episode_log
from drillgym.eval.logs.schema import COLUMN_NAMES, COLUMNS, LOG_SCHEMA_VERSION, SIM_COLUMNS
from drillgym.eval.logs.writer import EpisodeLogWriter

__all__ = [
    "COLUMNS",
    "COLUMN_NAMES",
    "LOG_SCHEMA_VERSION",
    "SIM_COLUMNS",
    "EpisodeLogError",
    "EpisodeLogWriter",
    "EpisodeLogger",
    "build_header",
    "package_versions",
    "read_episode_log",
]
