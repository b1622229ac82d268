"""Are people announced again after the onboard job is killed and restarted?

``sarmission run --sim`` (the simulated vehicle and camera, the default mission at 960x540) runs
for ``--first`` seconds and is killed with SIGKILL (no clean shutdown), then started again on
the same alert store for ``--second`` seconds. The simulator flies the same survey again from
its start, so the second run sees the people the first one alerted. Every alert of the second
run whose position lies within ``--near`` metres of an alert of the first run is counted as a
person announced again (a duplicate for the rescue team).

    python tools/restart_duplicates.py [--checkout DIR ...] [--repeats N]
"""

from __future__ import annotations

import argparse
import math
import os
import signal
import sqlite3
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pymap3d

from sarmission.commands.cli_helpers import free_udp_port

ROOT = Path(__file__).resolve().parents[1]


def run(checkout: Path, db: Path, seconds: float, kill: bool, log: Path) -> None:
    env = dict(os.environ, PYTHONPATH=str(checkout))
    cmd = [
        sys.executable,
        "-c",
        "import sys; from sarmission.cli import main; sys.exit(main())",
        "run",
        "--connect",
        f"udpin:127.0.0.1:{free_udp_port()}",
        "--sim",
        "--sim-size",
        "960x540",
        "--sim-fps",
        "30",
        "--alerts-db",
        str(db),
        "--connect-timeout",
        "10",
    ]
    if not kill:
        cmd += ["--duration", f"{seconds:g}"]
    with open(log, "ab") as out:
        proc = subprocess.Popen(cmd, cwd=checkout, env=env, stdout=out, stderr=subprocess.STDOUT)
        if kill:
            time.sleep(seconds)
            proc.send_signal(signal.SIGKILL)
        proc.wait(timeout=seconds + 120)


def alerts(db: Path) -> list[tuple[float, float, float, bool]]:
    """(lock time, lat, lon, confirmed) of every stored row with a position; a store from
    before alert tiers has every row confirmed."""
    with sqlite3.connect(db) as conn:
        columns = {row[1] for row in conn.execute("PRAGMA table_info(alerts)")}
        tier = "tier = 'confirmed'" if "tier" in columns else "1"
        rows = conn.execute(f"SELECT lock_time, lat, lon, {tier} FROM alerts ORDER BY seq")
        return [(t, lat, lon, bool(c)) for t, lat, lon, c in rows if lat is not None]


def metres(a: tuple[float, float], b: tuple[float, float]) -> float:
    n, e, _ = pymap3d.geodetic2ned(a[0], a[1], 0.0, b[0], b[1], 0.0)
    return math.hypot(n, e)


def measure(
    checkout: Path, first: float, second: float, near: float, work: Path
) -> tuple[int, int, int, int, int, int]:
    """Rows before the kill, after the restart, and after it within ``near`` of a row before:
    all rows (candidates included), then confirmed alerts only."""
    db, log = work / "alerts.db", work / "run.log"
    run(checkout, db, first, kill=True, log=log)
    before = alerts(db)
    restart = time.time()
    run(checkout, db, second, kill=False, log=log)
    after = [a for a in alerts(db) if a[0] >= restart]

    def again(now: list, earlier: list) -> int:
        return sum(1 for a in now if any(metres(a[1:3], b[1:3]) <= near for b in earlier))

    confirmed_before = [a for a in before if a[3]]
    confirmed_after = [a for a in after if a[3]]
    return (
        len(before),
        len(after),
        again(after, before),
        len(confirmed_before),
        len(confirmed_after),
        again(confirmed_after, confirmed_before),
    )


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument(
        "--checkout",
        type=Path,
        action="append",
        default=None,
        help="source tree whose sarmission runs; repeat to compare",
    )
    parser.add_argument("--first", type=float, default=25.0, help="seconds before SIGKILL")
    parser.add_argument("--second", type=float, default=30.0, help="seconds after restart")
    parser.add_argument(
        "--near",
        type=float,
        default=15.0,
        help="metres within which a new alert is the same person again",
    )
    parser.add_argument("--repeats", type=int, default=1)
    args = parser.parse_args()
    print(
        "| sarmission | run | rows before the kill | rows after the restart | of them within "
        f"{args.near:g} m of an earlier row | confirmed before | confirmed after | of them "
        f"within {args.near:g} m of an earlier confirmed alert |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for checkout in [c.resolve() for c in (args.checkout or [ROOT])]:
        rev = subprocess.run(
            ["git", "-C", str(checkout), "rev-parse", "--short", "HEAD"],
            capture_output=True,
            text=True,
        ).stdout.strip()
        for k in range(args.repeats):
            with tempfile.TemporaryDirectory(prefix="restart-") as tmp:
                figures = measure(checkout, args.first, args.second, args.near, Path(tmp))
            print(f"| {rev} | {k + 1} | " + " | ".join(map(str, figures)) + " |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
