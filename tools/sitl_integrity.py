"""Where do alerts land against a real autopilot? ``sarmission run`` against ArduPilot SITL.

Reproduces the way a user starts the onboard job: ArduPilot Copter SITL at 43.0 N 10.0 E (the
mission file's home is 54.17 N 7.89 E, 1,300 km away), ``sarmission run --connect ... --video
clip.mp4`` with the default mission, in two phases:

- ``boot``: started with the autopilot, before its GPS fix and HOME_POSITION, through arming and
  take-off (the vehicle on the ground first);
- ``survey``: started while the vehicle flies a 300 m box survey at 60 m in AUTO.

A pilot on SITL's ground-station port flies the vehicle and records its position. Every alert
in the run's store is compared with where the vehicle was when its position was computed (the
lock, or when a position was attached to an alert locked without one): a correct
fix lies inside the camera's footprint (well under 600 m at 60 m), so "over 600 m" counts
positions that are certainly wrong, and so is any position computed while the vehicle stood on
the ground (below 2 m), where the camera sees nothing it could place. The video shows a
rendered sea, not what SITL's vehicle sees, so only the distance to the vehicle is checked,
not the person.

    python tools/sitl_integrity.py --sitl ../shared/sitl/arducopter [--checkout DIR]

``--checkout`` runs the ``sarmission`` of another source tree (e.g. a ``git worktree`` of an
older commit) against the same clip and flight, for a before/after table.
"""

from __future__ import annotations

import argparse
import math
import os
import sqlite3
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "tests"))  # the SITL tier's harness: SITL process and pilot

from sitl_harness import Pilot, Sitl, box_survey, distance_m  # noqa: E402

WRONG_M = 600.0
#: Below this height above home the vehicle is on the ground (or landing): nothing in view can
#: be placed, so a position computed then is invented.
GROUNDED_M = 2.0


def render_clip(out: Path, frames: int, seed: int) -> Path:
    """A 960x540 maritime clip with swimmers from the first frame (the simulator's renderer)."""
    clip_dir = out / "clip"
    subprocess.run(
        [
            sys.executable,
            "-m",
            "sarmission.cli",
            "sim",
            "generate",
            "--scenario",
            "maritime_test",
            "--frames",
            str(frames),
            "--size",
            "960x540",
            "--seed",
            str(seed),
            "--out",
            str(clip_dir),
        ],
        check=True,
        stdout=subprocess.DEVNULL,
    )
    (video,) = sorted(clip_dir.glob("*.mp4"))
    return video


class Track:
    """The vehicle's positions as the pilot sees them: (POSIX time, lat, lon, rel alt)."""

    def __init__(self, pilot: Pilot) -> None:
        self.pilot = pilot
        self.points: list[tuple[float, float, float, float]] = []
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._record, daemon=True)
        self._thread.start()

    def _record(self) -> None:
        while not self._stop.wait(0.1):
            p = self.pilot.position()
            if p is not None and (p.lat or p.lon):
                self.points.append((time.time(), p.lat / 1e7, p.lon / 1e7, p.relative_alt / 1e3))

    def at(self, t: float) -> tuple[float, float, float, float] | None:
        if not self.points:
            return None
        return min(self.points, key=lambda p: abs(p[0] - t))

    def stop(self) -> None:
        self._stop.set()
        self._thread.join()


def start_run(
    checkout: Path, url: str, video: Path, db: Path, duration_s: float, log: Path
) -> subprocess.Popen[bytes]:
    env = dict(os.environ, PYTHONPATH=str(checkout))
    cmd = [
        sys.executable,
        "-c",
        "import sys; from sarmission.cli import main; sys.exit(main())",
        "run",
        "--connect",
        url,
        "--video",
        str(video),
        "--alerts-db",
        str(db),
        "--duration",
        f"{duration_s:g}",
        "--connect-timeout",
        "5",
    ]
    return subprocess.Popen(
        cmd, cwd=checkout, env=env, stdout=open(log, "wb"), stderr=subprocess.STDOUT
    )


def score(db: Path, track: Track, log: Path) -> dict[str, object]:
    """Alerts in ``db`` against the vehicle's track; the run's exit and tracebacks."""
    with sqlite3.connect(db) as conn:
        # a position attached after the lock was computed when it was attached (event time)
        rows = conn.execute(
            "SELECT a.lock_time, a.lat, a.lon, a.error_m, (SELECT MIN(e.time) FROM events e "
            "WHERE e.alert_id = a.alert_id AND e.kind = 'position') FROM alerts a"
        ).fetchall()
    distances, errors, grounded = [], [], 0
    for lock_time, lat, lon, error_m, attached in rows:
        if lat is None or lon is None:
            continue
        where = track.at(lock_time if attached is None else attached)
        if where is None:
            distances.append(math.inf)
            continue
        distances.append(distance_m(lat, lon, where[1], where[2]))
        errors.append(error_m)
        grounded += where[3] < GROUNDED_M
    text = log.read_text(errors="replace")
    wrong = [d for d, e in zip(distances, errors, strict=False) if d > WRONG_M]
    return {
        "alerts": len(rows),
        "placed": len(distances),
        "wrong": len(wrong),
        "grounded": grounded,
        "wrong_claimed_error": max(
            (e for d, e in zip(distances, errors, strict=False) if d > WRONG_M and e is not None),
            default=None,
        ),
        "median_m": statistics.median(distances) if distances else None,
        "max_m": max(distances) if distances else None,
        "tracebacks": text.count("Traceback"),
    }


def run_phase(
    phase: str,
    sitl_binary: Path,
    checkout: Path,
    video: Path,
    work: Path,
    duration_s: float,
    speedup: float,
) -> dict[str, object]:
    sitl = Sitl(sitl_binary, work / f"sitl-{phase}", speedup=speedup).start()
    pilot = Pilot(sitl.gcs_url)
    run = None
    db, log = work / f"alerts-{phase}.db", work / f"run-{phase}.log"
    try:
        pilot.wait_heartbeat()
        pilot.request_streams(4.0)
        track = Track(pilot)
        if phase == "boot":
            run = start_run(checkout, sitl.link_url, video, db, duration_s, log)
        pilot.wait_gps_fix()
        home = pilot.wait_home()
        pilot.fly_up(60.0)
        if phase == "survey":
            pilot.upload_mission(box_survey(home.latitude / 1e7, home.longitude / 1e7, 60.0))
            pilot.set_mode("AUTO")
            run = start_run(checkout, sitl.link_url, video, db, duration_s, log)
        assert run is not None
        code = run.wait(timeout=duration_s + 120)
        track.stop()
        result = score(db, track, log)
        result["exit"] = code
        return result
    finally:
        if run is not None and run.poll() is None:
            run.kill()
        pilot.close()
        sitl.stop()


def revision(checkout: Path) -> str:
    """The checkout's commit (short hash), as the table names it."""
    done = subprocess.run(
        ["git", "-C", str(checkout), "rev-parse", "--short", "HEAD"], capture_output=True, text=True
    )
    return done.stdout.strip() or str(checkout)


def table(rows: list[tuple[str, str, dict[str, object]]]) -> str:
    def fmt(v: object) -> str:
        return "-" if v is None else f"{v:.1f}" if isinstance(v, float) else str(v)

    lines = [
        "| sarmission | phase | alerts | with a position | placed with the vehicle on the "
        "ground | > 600 m from the vehicle | median m | max m | tracebacks | exit |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for rev, phase, r in rows:
        lines.append(
            f"| {rev} | {phase} | {r['alerts']} | {r['placed']} | {r['grounded']} | "
            f"{r['wrong']} | {fmt(r['median_m'])} | {fmt(r['max_m'])} | "
            f"{r['tracebacks']} | {r['exit']} |"
        )
    return "\n".join(lines)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sitl", required=True, type=Path, help="the arducopter binary")
    parser.add_argument(
        "--checkout",
        type=Path,
        action="append",
        default=None,
        help="source tree whose sarmission runs; repeat to compare several (default: this one)",
    )
    parser.add_argument("--duration", type=float, default=40.0, help="seconds per run")
    parser.add_argument("--speedup", type=float, default=4.0, help="SITL speed-up")
    parser.add_argument("--seed", type=int, default=4321, help="clip seed")
    parser.add_argument(
        "--repeats",
        type=int,
        default=1,
        help="runs of each phase per checkout (whether an alert falls in the "
        "seconds before HOME_POSITION arrives varies from run to run)",
    )
    args = parser.parse_args()
    checkouts = [c.resolve() for c in (args.checkout or [ROOT])]
    rows = []
    with tempfile.TemporaryDirectory(prefix="sitl-integrity-") as tmp:
        work = Path(tmp)
        video = render_clip(work, frames=450, seed=args.seed)
        for k, checkout in enumerate(checkouts):
            for phase in ("boot", "survey"):
                for r in range(args.repeats):
                    run_dir = work / f"{k}-{phase}-{r}"
                    run_dir.mkdir()
                    result = run_phase(
                        phase, args.sitl, checkout, video, run_dir, args.duration, args.speedup
                    )
                    rows.append((revision(checkout), phase, result))
    print(
        f"ArduPilot SITL speed-up {args.speedup:g}, {args.duration:g} s per run, clip seed "
        f"{args.seed}"
    )
    print(table(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
