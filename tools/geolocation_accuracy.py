"""Geolocation accuracy and alert latency of the live pipeline, independent of the detector.

The simulated vehicle serves its flight over real UDP on 127.0.0.1 and the real mission
controller runs against it (MAVLink link, telemetry buffer with boot-clock mapping and slerp,
tracker, m-of-k lock, geolocation, durable alert store, STATUSTEXT / ROI actions). Only MITE-Net
is replaced: an oracle detector reports the simulator's true boxes of the swimmers in each
delivered frame, with seeded Gaussian noise of ``box_noise_px`` per box edge, and the true image
shift of the ground between frames (what vSTMD's ego-motion read-out gives MITE-Net's tracker).
So what is measured is everything after perception.

Per run:

- swimmers in view (in at least ``lock.m`` delivered frames), alerted, missed, duplicate alerts;
- geolocation error of each alert against the simulator's truth position of that swimmer at the
  lock frame (median, 95th percentile, max), next to the alert's own estimate ``error_m``;
- the error floor: the same pixel (the tracker's filtered box centre) geolocated with the
  simulator's exact camera pose, i.e. the part of the error that is not telemetry or timing;
- lock-to-alert latency: from the lock frame's capture time to the alert being durably stored,
  to the STATUSTEXT reaching the vehicle, and to the store's delivery records (STATUSTEXT
  confirmed, ROI command acknowledged);
- CPU: the controller's per-frame work (thread CPU time inside ``MissionController.process``),
  the MAVLink threads (reader, housekeeping, outbox), the simulated camera's rendering and the
  vehicle, each as a share of wall time.

Usage::

    python tools/geolocation_accuracy.py [--duration 40] [--size 960x540] [--hfov 35] [--seed 0]
        [--telemetry exact|noisy|both] [--fps 15] [--box-noise 0.5]
        [--gimbal-report vehicle|earth] [--json]

Exact telemetry: gnss_noise_m = attitude_noise_deg = latency_s = 0. Noisy: gnss_noise_m = 2,
attitude_noise_deg = 1, latency_s = 0.05 (mission overrides of ``[telemetry]``).
"""

from __future__ import annotations

import argparse
import json
import math
import sqlite3
import statistics
import sys
import tempfile
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

from sarmission.commands.cli_helpers import free_udp_port, parse_frame_size  # noqa: E402
from sarmission.commands.demo import DEMO_MISSION, DEMO_OVERRIDES  # noqa: E402
from sarmission.geo.camera import intersect_ground, pixel_rays, project_points  # noqa: E402
from sarmission.mission.actions import ascii_statustext  # noqa: E402
from sarmission.mission.config import MissionConfig, load_mission  # noqa: E402
from sarmission.mission.targets import distance_m  # noqa: E402
from sarmission.perception.types import Detections, FrameResult, Proposals  # noqa: E402
from sim.scene import TARGET_CATEGORIES  # noqa: E402

#: ``[telemetry]`` overrides of the two configurations.
TELEMETRY: dict[str, dict[str, float]] = {
    "exact": {
        "telemetry.gnss_noise_m": 0.0,
        "telemetry.attitude_noise_deg": 0.0,
        "telemetry.latency_s": 0.0,
    },
    "noisy": {
        "telemetry.gnss_noise_m": 2.0,
        "telemetry.attitude_noise_deg": 1.0,
        "telemetry.latency_s": 0.05,
    },
}
#: An alert belongs to the true swimmer whose box centre is within this many px of the alert's
#: pixel at the lock frame (as ``sarmission demo`` scores).
MATCH_PX = 24.0


class OracleDetector:
    """MITE-Net's ``process`` interface answering with the simulator's truth for the frame the
    camera delivered last: every swimmer's box plus N(0, ``noise_px``) per edge, score 0.9.

    ``true_shift``: also report the image shift of static ground since the previous frame
    (exact poses), as vSTMD does for the real detector; else no shift is known.
    """

    classes: tuple[str, ...] = TARGET_CATEGORIES

    def __init__(
        self, camera: Any, noise_px: float = 0.5, seed: int = 0, true_shift: bool = True
    ) -> None:
        if noise_px < 0:
            raise ValueError(f"box noise must be >= 0 px, got {noise_px}")
        self.camera = camera
        self.noise_px = noise_px
        self.true_shift = true_shift
        self.rng = np.random.default_rng([seed, 7])
        self.per_stage_ms: dict[str, float] = {}
        self.calls = 0
        self.boxes_reported = 0
        self._prev_time: float | None = None

    def process(
        self,
        frame_bgr: np.ndarray,
        timestamp: float,
        shift_px: tuple[float, float] | None = None,
        person_px: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> FrameResult:
        truth = self.camera.truth[-1]  # the frame the controller is processing now
        self.calls += 1
        w, h = self.camera.intrinsics.width, self.camera.intrinsics.height
        boxes, classes = [], []
        for a in truth.targets:
            if a.visibility <= 0:
                continue
            b = np.asarray(a.bbox_xyxy, float) + self.rng.normal(0.0, self.noise_px, 4)
            b[[0, 2]] = np.clip(np.sort(b[[0, 2]]), 0.0, w)
            b[[1, 3]] = np.clip(np.sort(b[[1, 3]]), 0.0, h)
            if b[2] - b[0] < 1.0 or b[3] - b[1] < 1.0:
                continue
            boxes.append(b)
            classes.append(self.classes.index(a.category) if a.category in self.classes else 0)
        self.boxes_reported += len(boxes)
        shift = self._shift(truth.sim_time) if self.true_shift else None
        det = Detections(
            np.asarray(boxes, np.float32).reshape(-1, 4),
            np.full(len(boxes), 0.9, np.float32),
            np.asarray(classes, np.int64),
        )
        return FrameResult(timestamp, det, Proposals(boxes=det.boxes.copy()), None, shift)

    def _shift(self, t: float) -> tuple[float, float] | None:
        """Where the ground point at the image centre of the previous frame moved in this one."""
        prev, self._prev_time = self._prev_time, t
        if prev is None:
            return None
        intr = self.camera.intrinsics
        vehicle = self.camera.vehicle
        centre = np.array([[intr.cx, intr.cy]])
        before = vehicle.camera_pose(prev)
        ground, ok = intersect_ground(before, pixel_rays(intr, before, centre))
        if not ok[0]:
            return None
        uv, front = project_points(intr, vehicle.camera_pose(t), ground)
        if not front[0]:
            return None
        return float(uv[0, 0] - intr.cx), float(uv[0, 1] - intr.cy)


@dataclass
class _Clock:
    """Accumulated thread CPU and wall time of the calls of one wrapped function."""

    cpu_s: float = 0.0
    wall_s: float = 0.0
    calls: int = 0


def _timed(fn: Any, clock: _Clock, after: Any = None) -> Any:
    """``fn`` with its thread CPU and wall time added to ``clock``; ``after(args, result)`` is
    called untimed once it returns."""

    def wrapper(*args: Any, **kwargs: Any) -> Any:
        c0, w0 = time.thread_time(), time.perf_counter()
        try:
            result = fn(*args, **kwargs)
        finally:
            clock.cpu_s += time.thread_time() - c0
            clock.wall_s += time.perf_counter() - w0
            clock.calls += 1
        if after is not None:
            after(args, result)
        return result

    return wrapper


class _LookupRecorder:
    """Wraps ``TelemetryBuffer.lookup`` to keep, per requested time, the first answer the
    controller got and the newest gimbal sample time then (cleared each frame)."""

    def __init__(self, telemetry: Any) -> None:
        self.telemetry = telemetry
        self.lookup = telemetry.lookup
        self.seen: dict[float, tuple[Any, float | None]] = {}
        telemetry.lookup = self

    def __call__(self, t: float) -> Any:
        pose = self.lookup(t)
        if t not in self.seen:
            self.seen[t] = (pose, self.telemetry.newest_time("gimbal"))
        return pose


def _pose_check(
    seen: tuple[Any, float | None],
    camera: Any,
    home: tuple[float, float, float],
    frame_index: int,
    timestamp: float,
) -> dict[str, float | None]:
    """How far the telemetry pose the controller used for a frame is from the exact one: camera
    pointing (deg), horizontal position (m), and the age of the newest gimbal sample (s)."""
    from sarmission.geo.frames import rotation_ned_from_camera
    from sarmission.geo.geolocate import PlatformPose
    from sarmission.geo.wgs84 import geodetic_to_ned

    pose, gimbal = seen
    out: dict[str, float | None] = {
        "pointing_error_deg": None,
        "position_error_m": None,
        "gimbal_age_s": None if gimbal is None else timestamp - gimbal,
    }
    if not isinstance(pose, PlatformPose):
        return out
    exact = camera.vehicle.camera_pose(camera.truth[frame_index].sim_time)
    r = rotation_ned_from_camera(
        (pose.roll, pose.pitch, pose.yaw), pose.gimbal_rpy, pose.gimbal_frame
    )
    d = r.T @ exact.rotation_ned_from_camera
    out["pointing_error_deg"] = math.degrees(math.acos(min(1.0, max(-1.0, (np.trace(d) - 1) / 2))))
    n, e, _ = geodetic_to_ned(pose.lat, pose.lon, home[2] + pose.rel_alt_m, *home)
    out["position_error_m"] = float(
        math.hypot(float(n) - exact.position_ned[0], float(e) - exact.position_ned[1])
    )
    return out


def _thread_cpu() -> dict[str, float]:
    """CPU seconds (user + system) so far of each named thread of this process."""
    names = {t.native_id: t.name for t in threading.enumerate()}
    try:
        import psutil

        rows = [(th.id, th.user_time + th.system_time) for th in psutil.Process().threads()]
    except ImportError:  # Linux without psutil: /proc/self/task/<tid>/stat
        import os

        tick = os.sysconf("SC_CLK_TCK")
        rows = []
        for tid in os.listdir("/proc/self/task"):
            try:
                fields = Path(f"/proc/self/task/{tid}/stat").read_text().rsplit(")", 1)[1].split()
            except OSError:
                continue
            rows.append((int(tid), (int(fields[11]) + int(fields[12])) / tick))
    out: dict[str, float] = {}
    for tid, cpu in rows:
        name = names.get(tid, "other")
        out[name] = out.get(name, 0.0) + cpu
    return out


def accuracy_mission(
    size: tuple[int, int], hfov: float, telemetry: str, policy: tuple[str, ...] | None = None
) -> MissionConfig:
    """The shortened maritime demo mission with the given frames and telemetry quality
    (``policy``: the action policy, default the demo's ``alert, roi``)."""
    overrides: dict[str, Any] = dict(DEMO_OVERRIDES)
    overrides.update(
        {
            "camera.width": size[0],
            "camera.height": size[1],
            "camera.hfov_deg": hfov,
            **TELEMETRY[telemetry],
        }
    )
    if policy is not None:
        overrides["actions.policy"] = list(policy)
    return load_mission(DEMO_MISSION, overrides)


def _stats(values: list[float]) -> dict[str, float | None]:
    if not values:
        return {"n": 0, "median": None, "p95": None, "max": None, "mean": None}
    v = np.asarray(values, float)
    return {
        "n": len(values),
        "median": float(np.median(v)),
        "p95": float(np.percentile(v, 95)),
        "max": float(v.max()),
        "mean": float(v.mean()),
    }


def _exact_fix_error(camera: Any, frame_index: int, uv: tuple[float, float], truth: Any) -> float:
    """Ground distance (m) between the truth and pixel ``uv`` geolocated with the exact pose."""
    intr = camera.intrinsics
    pose = camera.vehicle.camera_pose(camera.truth[frame_index].sim_time)
    ground, ok = intersect_ground(
        pose, pixel_rays(intr, pose, np.array([uv])), float(truth.position_ned[2])
    )
    if not ok[0]:
        return math.nan
    return float(
        math.hypot(ground[0, 0] - truth.position_ned[0], ground[0, 1] - truth.position_ned[1])
    )


def measure(
    duration_s: float = 40.0,
    size: tuple[int, int] = (960, 540),
    hfov: float = 35.0,
    seed: int = 0,
    telemetry: str = "exact",
    fps: float | None = 15.0,
    box_noise_px: float = 0.5,
    true_shift: bool = True,
    policy: tuple[str, ...] | None = None,
    workdir: str | Path | None = None,
    console: Any = None,
    gimbal_report: str = "vehicle",
) -> dict[str, Any]:
    """One live run with the oracle detector; returns the measurements (see the module doc).
    ``gimbal_report``: the simulated gimbal reports its yaw relative to the heading ("vehicle",
    ArduPilot's way) or to north ("earth")."""
    from sarmission.mission.live import LiveSession
    from sim.camera import SimCamera, mission_scenario
    from sim.vehicle import SimVehicle

    if telemetry not in TELEMETRY:
        raise ValueError(f"telemetry must be one of {sorted(TELEMETRY)}, got {telemetry!r}")
    mission = accuracy_mission(size, hfov, telemetry, policy)
    lines: list[str] = []
    say = console or lines.append
    with tempfile.TemporaryDirectory(dir=workdir) as tmp:
        db = Path(tmp) / "alerts.db"
        port = free_udp_port()
        vehicle = SimVehicle(
            f"udpout:127.0.0.1:{port}",
            mission,
            seed=seed,
            stream_on_request=True,
            gimbal_report=gimbal_report,
        ).start()
        try:
            camera = SimCamera(
                vehicle, scenario=mission_scenario(vehicle, seed=seed), size=size, fps=fps
            )
            detector = OracleDetector(camera, box_noise_px, seed, true_shift)
            session = LiveSession(
                mission,
                detector,
                camera,
                f"udpin:127.0.0.1:{port}",
                str(db),
                transport_latency_s=mission.telemetry.latency_s,
                connect_timeout_s=10.0,
                console=say,
            )
            controller = session.controller
            process_clock, render_clock = _Clock(), _Clock()
            checks: dict[str, dict[str, float | None]] = {}
            lookups = _LookupRecorder(session.telemetry)

            def check(args: tuple, new_alerts: list) -> None:
                for alert in new_alerts:
                    if args[1] in lookups.seen:
                        checks[alert.alert_id] = _pose_check(
                            lookups.seen[args[1]], camera, mission.area.home, args[0], args[1]
                        )
                lookups.seen.clear()

            controller.process = _timed(controller.process, process_clock, check)
            camera.read = _timed(camera.read, render_clock)
            cpu0, wall0 = _thread_cpu(), time.perf_counter()
            try:
                session.run(duration_s=duration_s)
            finally:
                wall = time.perf_counter() - wall0
                cpu1 = _thread_cpu()
                # sim time -> local monotonic (speedup 1): mono = sim + (now - sim_time())
                sim_to_mono = time.monotonic() - vehicle.sim_time()
                alerts = list(controller.stats.alerts)
                summary = session.close()
        finally:
            vehicle.stop()
        with sqlite3.connect(db) as conn:
            added = dict(conn.execute("SELECT alert_id, added_time FROM alerts"))
            # commands: acknowledged (accepted); STATUSTEXT: first sent (nothing acknowledges it)
            delivered: dict[tuple[str, str], float] = {
                (a, ch): t
                for a, ch, t in conn.execute(
                    "SELECT alert_id, channel, time FROM acks WHERE result = 0 UNION ALL "
                    "SELECT alert_id, channel, first FROM sends"
                )
            }
    to_posix = controller.to_posix
    return _report(
        mission,
        telemetry,
        camera,
        vehicle,
        alerts,
        added,
        delivered,
        lambda sim_t: to_posix(sim_t + sim_to_mono),
        wall,
        process_clock,
        render_clock,
        {k: cpu1.get(k, 0.0) - cpu0.get(k, 0.0) for k in cpu1},
        detector,
        summary,
        lines,
        duration_s,
        size,
        hfov,
        seed,
        fps,
        box_noise_px,
        checks,
    )


def _report(
    mission: MissionConfig,
    telemetry: str,
    camera: Any,
    vehicle: Any,
    alerts: list,
    added: dict[str, float],
    delivered: dict[tuple[str, str], float],
    sim_to_posix: Any,
    wall: float,
    process_clock: _Clock,
    render_clock: _Clock,
    cpu: dict[str, float],
    detector: OracleDetector,
    summary: str,
    lines: list[str],
    duration_s: float,
    size: tuple[int, int],
    hfov: float,
    seed: int,
    fps: float | None,
    box_noise_px: float,
    checks: dict[str, dict[str, float | None]],
) -> dict[str, Any]:
    min_frames = mission.lock.m
    frames_seen: dict[int, int] = {}
    for frame in camera.truth:
        for a in frame.targets:
            frames_seen[a.track_id] = frames_seen.get(a.track_id, 0) + 1
    in_view = {tid for tid, n in frames_seen.items() if n >= min_frames}

    texts = [(s.text, s.sim_time) for s in vehicle.statustexts]
    rows, found, duplicates, false_alerts = [], set(), 0, 0
    for alert in alerts:
        _, cx, cy = alert.pixel_track[-1]
        best, best_d = None, MATCH_PX
        for a in camera.targets_at(alert.frame_index):
            x0, y0, x1, y1 = a.bbox_xyxy
            d = math.hypot((x0 + x1) / 2 - cx, (y0 + y1) / 2 - cy)
            if d <= best_d:
                best, best_d = a, d
        row: dict[str, Any] = {
            "target_id": alert.target_id,
            "frame": alert.frame_index,
            "swimmer": None if best is None else best.track_id,
            "error_m": None,
            "estimated_m": alert.error_m,
            "exact_pose_error_m": None,
            "pixel_offset_px": None,
        }
        if best is None:
            false_alerts += 1
        else:
            if best.track_id in found:
                duplicates += 1
                row["duplicate"] = True
            found.add(best.track_id)
            row["pixel_offset_px"] = best_d
            row["exact_pose_error_m"] = _exact_fix_error(camera, alert.frame_index, (cx, cy), best)
            if alert.position is not None and best.lat is not None:
                row["error_m"] = distance_m(alert.position, (best.lat, best.lon))
        row.update(checks.get(alert.alert_id, {}))
        t_lock = alert.lock_time
        if alert.alert_id in added:
            row["stored_s"] = added[alert.alert_id] - t_lock
        text = ascii_statustext(alert)
        for i, (txt, sim_t) in enumerate(texts):
            if txt == text:
                row["statustext_at_vehicle_s"] = sim_to_posix(sim_t) - t_lock
                del texts[i]
                break
        for channel, key in (("mavlink", "mavlink_sent_s"), ("mavlink_roi", "mavlink_roi_acked_s")):
            if (alert.alert_id, channel) in delivered:
                row[key] = delivered[(alert.alert_id, channel)] - t_lock
        rows.append(row)

    def col(key: str) -> list[float]:
        return [r[key] for r in rows if r.get(key) is not None and not math.isnan(r[key])]

    errors = col("error_m")
    estimated = [
        r["estimated_m"]
        for r in rows
        if r.get("error_m") is not None and r["estimated_m"] is not None
    ]
    within = sum(
        1
        for r in rows
        if r.get("error_m") is not None
        and r["estimated_m"] is not None
        and r["error_m"] <= r["estimated_m"]
    )
    frames = process_clock.calls
    mavlink_threads = (
        "mavlink-reader",
        "mavlink-housekeeping",
        "mavlink-outbox",
        "mavlink-outbox-text",
    )
    link_cpu = sum(cpu.get(n, 0.0) for n in mavlink_threads)
    return {
        "telemetry": telemetry,
        "settings": {
            "duration_s": duration_s,
            "size": f"{size[0]}x{size[1]}",
            "hfov_deg": hfov,
            "seed": seed,
            "fps": fps,
            "box_noise_px": box_noise_px,
            "policy": list(mission.actions.policy),
            "altitude_m": mission.flight.altitude_m,
            "speed_m_s": mission.flight.speed_m_s,
            **{k.split(".")[1]: v for k, v in TELEMETRY[telemetry].items()},
        },
        "frames": frames,
        "swimmers_in_view": len(in_view),
        "alerted": len(found & in_view),
        "alerted_briefly_seen": len(found - in_view),
        "missed": sorted(in_view - found),
        "missed_detail": _missed_detail(camera, in_view - found, found),
        "alerts": len(alerts),
        "duplicates": duplicates,
        "false_alerts": false_alerts,
        "error_m": _stats(errors),
        "exact_pose_error_m": _stats(col("exact_pose_error_m")),
        "pointing_error_deg": _stats(col("pointing_error_deg")),
        "position_error_m": _stats(col("position_error_m")),
        "gimbal_age_s": _stats(col("gimbal_age_s")),
        "estimated_error_mean_m": statistics.fmean(estimated) if estimated else None,
        "actual_error_mean_m": statistics.fmean(errors) if errors else None,
        "actual_within_estimate": within,
        "latency_s": {
            k: _stats(col(k))
            for k in (
                "stored_s",
                "statustext_at_vehicle_s",
                "mavlink_sent_s",
                "mavlink_roi_acked_s",
            )
        },
        "cpu": {
            "wall_s": wall,
            "controller_process_share": process_clock.cpu_s / wall,
            "controller_process_ms_per_frame": 1000 * process_clock.cpu_s / max(frames, 1),
            "mavlink_threads_share": link_cpu / wall,
            "controller_total_share": (process_clock.cpu_s + link_cpu) / wall,
            "camera_render_share": render_clock.cpu_s / wall,
            "vehicle_share": cpu.get("sim-vehicle", 0.0) / wall,
            "fps": frames / wall,
        },
        "per_alert": rows,
        "summary": summary,
        "console": lines,
    }


def _missed_detail(camera: Any, missed: set[int], found: set[int]) -> list[dict[str, Any]]:
    """Per missed swimmer: frames it was in, and the ground distance (m) to the nearest alerted
    swimmer when last seen (within the registry's merge radius its track joined that target)."""
    last: dict[int, Any] = {}
    frames: dict[int, int] = {}
    for frame in camera.truth:
        for a in frame.targets:
            last[a.track_id] = a
            frames[a.track_id] = frames.get(a.track_id, 0) + 1
    out = []
    for tid in sorted(missed):
        p = last[tid].position_ned
        near = [
            math.hypot(p[0] - last[f].position_ned[0], p[1] - last[f].position_ned[1])
            for f in found
            if f in last
        ]
        out.append(
            {
                "swimmer": tid,
                "frames": frames[tid],
                "nearest_alerted_m": min(near) if near else None,
            }
        )
    return out


def _f(value: float | None, digits: int = 2) -> str:
    return "-" if value is None else f"{value:.{digits}f}"


def markdown(results: list[dict[str, Any]]) -> str:
    """The results of one or more runs as one Markdown table (a column per run)."""
    head = (
        "| | "
        + " | ".join(f"{r['telemetry']} ({', '.join(r['settings']['policy'])})" for r in results)
        + " |"
    )
    rows: list[tuple[str, list[str]]] = []

    def add(label: str, fn: Any) -> None:
        rows.append((label, [fn(r) for r in results]))

    add("frames processed (fps)", lambda r: f"{r['frames']} ({r['cpu']['fps']:.1f})")
    add("swimmers in view (>= 3 frames)", lambda r: str(r["swimmers_in_view"]))
    add(
        "alerted",
        lambda r: (
            f"{r['alerted']}"
            + (f" (+{r['alerted_briefly_seen']} seen briefly)" if r["alerted_briefly_seen"] else "")
        ),
    )
    add(
        "alerts / duplicates / false",
        lambda r: f"{r['alerts']} / {r['duplicates']} / {r['false_alerts']}",
    )
    for key, label in (("median", "median"), ("p95", "95th pct"), ("max", "max")):
        add(f"geolocation error {label} (m)", lambda r, k=key: _f(r["error_m"][k]))
    add(
        "error with exact pose, median / max (m)",
        lambda r: f"{_f(r['exact_pose_error_m']['median'])} / {_f(r['exact_pose_error_m']['max'])}",
    )
    add(
        "telemetry pose at lock: pointing error median / max (deg)",
        lambda r: f"{_f(r['pointing_error_deg']['median'])} / {_f(r['pointing_error_deg']['max'])}",
    )
    add(
        "telemetry pose at lock: position error median / max (m)",
        lambda r: f"{_f(r['position_error_m']['median'])} / {_f(r['position_error_m']['max'])}",
    )
    add(
        "newest gimbal sample age at lock, median / max (s)",
        lambda r: f"{_f(r['gimbal_age_s']['median'], 3)} / {_f(r['gimbal_age_s']['max'], 3)}",
    )
    add(
        "mean estimated error_m vs actual (m)",
        lambda r: f"{_f(r['estimated_error_mean_m'])} vs {_f(r['actual_error_mean_m'])}",
    )
    add("actual within estimate", lambda r: f"{r['actual_within_estimate']} of {r['error_m']['n']}")
    for key, label in (
        ("stored_s", "lock -> stored"),
        ("statustext_at_vehicle_s", "lock -> STATUSTEXT at vehicle"),
        ("mavlink_sent_s", "lock -> STATUSTEXT first sent (store)"),
        ("mavlink_roi_acked_s", "lock -> ROI acknowledged (store)"),
    ):
        add(
            f"{label}, median / max (ms)",
            lambda r, k=key: (
                "-"
                if r["latency_s"][k]["n"] == 0
                else (
                    f"{1000 * r['latency_s'][k]['median']:.0f} / "
                    f"{1000 * r['latency_s'][k]['max']:.0f}"
                )
            ),
        )
    add(
        "controller CPU: process() (ms/frame)",
        lambda r: (
            f"{100 * r['cpu']['controller_process_share']:.1f}% "
            f"({r['cpu']['controller_process_ms_per_frame']:.1f})"
        ),
    )
    add(
        "controller CPU: MAVLink threads",
        lambda r: f"{100 * r['cpu']['mavlink_threads_share']:.1f}%",
    )
    add("controller CPU: total", lambda r: f"{100 * r['cpu']['controller_total_share']:.1f}%")
    add(
        "sim camera render / vehicle CPU",
        lambda r: (
            f"{100 * r['cpu']['camera_render_share']:.1f}% / {100 * r['cpu']['vehicle_share']:.1f}%"
        ),
    )
    out = [head, "|---|" + "---|" * len(results)]
    out += [f"| {label} | " + " | ".join(vals) + " |" for label, vals in rows]
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--duration", type=float, default=40.0, help="seconds of flight per run")
    parser.add_argument("--size", default="960x540", help="frame size WxH")
    parser.add_argument("--hfov", type=float, default=35.0, help="horizontal FOV in degrees")
    parser.add_argument("--seed", type=int, default=0, help="scenario, flight and noise seed")
    parser.add_argument("--telemetry", choices=("exact", "noisy", "both"), default="both")
    parser.add_argument(
        "--fps", type=float, default=15.0, help="camera frame rate cap (0: as fast as processed)"
    )
    parser.add_argument(
        "--box-noise", type=float, default=0.5, help="oracle box noise, px (1-sigma per edge)"
    )
    parser.add_argument(
        "--no-shift",
        action="store_true",
        help="give the tracker no camera shift (as without vSTMD)",
    )
    parser.add_argument(
        "--policy",
        default="alert,roi",
        help="action policy, comma-separated (default: %(default)s, the demo's; "
        "roi slews the gimbal towards each alerted swimmer)",
    )
    parser.add_argument(
        "--gimbal-report",
        choices=("vehicle", "earth"),
        default="vehicle",
        help="the gimbal's yaw relative to the heading or to north",
    )
    parser.add_argument("--json", action="store_true", help="print JSON instead of Markdown")
    args = parser.parse_args(argv)
    import logging

    logging.getLogger("sim.vehicle").setLevel(logging.ERROR)  # one line per STATUSTEXT
    size = parse_frame_size(args.size)
    configs = ["exact", "noisy"] if args.telemetry == "both" else [args.telemetry]
    results = []
    for config in configs:
        if not args.json:
            print(f"running {config} telemetry for {args.duration:g} s ...", flush=True)
        results.append(
            measure(
                args.duration,
                size,
                args.hfov,
                args.seed,
                config,
                args.fps or None,
                args.box_noise,
                not args.no_shift,
                tuple(p.strip() for p in args.policy.split(",") if p.strip()),
                gimbal_report=args.gimbal_report,
            )
        )
    if args.json:
        print(json.dumps(results, indent=2))
    else:
        print(markdown(results))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
