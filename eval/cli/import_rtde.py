"""``drillgym import-rtde SESSION... --out DIR``: recording sessions -> episode logs (Parquet, real schema)."""

from __future__ import annotations

import argparse
import sys
from pathlib import Path


def add_arguments(parser: argparse.ArgumentParser) -> None:
    """CLI arguments."""
    parser.add_argument(
        "sessions",
        nargs="+",
        type=Path,
        help="session folders (rtde.csv, ft.csv, tracker.csv, commands.csv, header.json)",
    )
    parser.add_argument("--out", required=True, type=Path, help="folder for <session>.parquet")
    parser.add_argument("--overwrite", action="store_true", help="replace existing logs")


def run(args: argparse.Namespace) -> int:
    """Import every session; report the ones that fail their checks."""
    from drillgym.eval.diagnosis.episodes import episode_from_log
    from drillgym.eval.diagnosis.rtde_import import import_session
    from drillgym.eval.diagnosis.validate import LogCheckError
    from drillgym.eval.logs import EpisodeLogWriter

    failed = 0
    for session in args.sessions:
        try:
            header, frame = import_session(session)
            ep = episode_from_log(session.name, header, frame)  # the diagnosis's checks, before writing
            header["run"]["repairs"] = header["run"].get("repairs", []) + ep.repairs
            args.out.mkdir(parents=True, exist_ok=True)  # only once a session has passed its checks
            writer = EpisodeLogWriter(args.out / f"{session.name}.parquet", header, overwrite=args.overwrite)
            writer.append({c: frame[c].to_numpy() for c in writer.schema.names})
            path = writer.close()
            print(f"{session} -> {path} ({len(frame)} samples)")
        except (LogCheckError, OSError, ValueError) as e:
            failed += 1
            print(f"drillgym import-rtde: error: {session}: {' '.join(str(e).split())}", file=sys.stderr)
    return 2 if failed else 0
