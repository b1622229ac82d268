"""A real autopilot's logs against the footage of the same flight: ArduCopter SITL takes off and
flies a survey; its DataFlash .BIN and a tlog recorded with pymavlink on the ground-station port
are kept; the simulator renders the clip the hard-mounted nadir camera saw from SITL's own truth
(``SIM``), starting at a camera trigger; ``sarmission replay`` runs clip + log. Positions must
meet the geolocation goal, alignment from the tlog must agree with the .BIN's trigger.

Skipped unless ``$SARMISSION_SITL`` names the ``arducopter`` binary. The detector is scripted
from the rendered ground truth: the test is about telemetry, alignment and geolocation.
"""

from __future__ import annotations

import csv
import dataclasses
import math
import struct
import time
from pathlib import Path

import numpy as np
import pytest
from scripted_detector import ScriptedDetector
from sitl_harness import Pilot, Sitl, box_survey, wait_for

from sarmission.cli import main
from sarmission.data.coco_video import read_coco_video
from sarmission.flightlog.align import align_video
from sarmission.flightlog.detect import open_flight_log
from sarmission.flightlog.video_time import creation_time, set_creation_time
from sarmission.geo.wgs84 import geodetic_to_ned
from sarmission.mission.config import load_mission
from sim.generate import generate_sequence
from sim.log_flight import LogFlight
from sim.scene import Scenario

HOME = (43.0, 10.0, 120.0, 0.0)
ALT = 40.0
FPS = 10.0
FRAMES = 60
#: The geolocation goal with real (estimated, noisy) telemetry: a few metres.
GOAL_M = 3.0


def fly(sitl_binary: Path, work: Path) -> tuple[Path, Path]:
    """Boot, enable the camera trigger, power-cycle, take off, survey north, trigger the
    camera once at speed; returns (DataFlash .BIN, tlog)."""
    from pymavlink.dialects.v20 import ardupilotmega as mav

    sitl = Sitl(sitl_binary, work / "sitl", speedup=10, home=HOME)
    pilot = Pilot(sitl.gcs_url)
    tlog_path = work / "flight.tlog"
    tlog = tlog_path.open("wb")

    def record(_conn: object, msg: object) -> None:  # what mavutil writes to a logfile
        if msg.get_type() != "BAD_DATA":
            tlog.write(struct.pack(">Q", int(time.time() * 1e6) & ~3) + msg.get_msgbuf())

    pilot.conn.message_hooks.append(record)
    sitl.start()
    try:
        pilot.wait_heartbeat(60)
        pilot.set_param("CAM1_TYPE", 1)  # a servo-triggered camera: CAM messages on trigger
        sitl.restart()
        pilot.forget("GLOBAL_POSITION_INT", "HOME_POSITION", "HEARTBEAT")
        wait_for(lambda: pilot.latest("HEARTBEAT"), 60)
        pilot.request_streams(10)
        pilot.wait_gps_fix()
        pilot.wait_home()
        pilot.fly_up(ALT)
        assert pilot.upload_mission(box_survey(HOME[0], HOME[1], ALT, 300.0, 5.0)) == 0
        pilot.set_mode("AUTO")
        assert wait_for(lambda: (p := pilot.position()) is not None and p.vx > 450, 60)
        ack = pilot.command_long(mav.MAV_CMD_DO_DIGICAM_CONTROL, 0, 0, 0, 0, 1)
        assert ack is not None and ack.result == mav.MAV_RESULT_ACCEPTED
        assert wait_for(lambda: pilot.latest("CAMERA_FEEDBACK"), 30)
        time.sleep(FRAMES / FPS / 10 + 1.0)  # the clip's length at 10x, and a second more
    finally:
        pilot.close()
        tlog.close()
        sitl.stop()
    logs = sorted((work / "sitl" / "logs").glob("*.BIN"))
    assert logs, "SITL wrote no DataFlash log"
    return logs[-1], tlog_path


def test_replay_of_a_sitl_flight_with_its_logs(
    sitl_binary: Path, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys
) -> None:
    bin_path, tlog_path = fly(sitl_binary, tmp_path)
    log = open_flight_log(bin_path)
    tlog = open_flight_log(tlog_path)
    assert len(log.triggers) == 1 and len(tlog.triggers) == 1
    start = log.triggers[0]

    mission_file = tmp_path / "sitl.toml"
    mission_file.write_text(
        f"[area]\nhome_lat = {HOME[0]}\nhome_lon = {HOME[1]}\n"
        "[camera]\nwidth = 640\nheight = 360\nhfov_deg = 70.0\nmount_pitch_deg = -90.0\n"
        "gimbal = false\n[flight]\naltitude_m = 40.0\n"
    )
    mission = load_mission(mission_file)
    flight = LogFlight(bin_path, mission, home=log.home)
    p0 = flight.state_at(start).position_ned
    scenario = Scenario(
        kind="maritime",
        seed=3,
        sea_state=1,
        n_swimmers=10,
        area_ne=(p0[0] + 10, p0[1] - 12, p0[0] + 40, p0[1] + 12),
    )
    ann_path = generate_sequence(
        scenario,
        flight,
        FRAMES,
        size=(640, 360),
        out_dir=tmp_path,
        fps=FPS,
        start_s=start,
        progress=False,
        name="clip",
    )
    clip = tmp_path / "clip.mp4"
    assert log.utc_offset_s is not None
    set_creation_time(clip, start + log.utc_offset_s)
    gt = read_coco_video(ann_path)
    script: list[list] = [[] for _ in range(FRAMES)]
    truth: dict[int, tuple[float, float]] = {}
    for ann in gt.annotations:
        if ann.extra.get("is_target") and ann.gt_lat is not None:
            x, y, w, h = ann.bbox
            script[ann.image_id - 1].append(((x, y, x + w, y + h), 0.95, 0))
            truth[ann.track_id] = (ann.gt_lat, ann.gt_lon)
    assert len(truth) >= 3, "the clip shows too few people"

    errors = {}
    for name, telemetry in (("bin", bin_path), ("tlog", tlog_path)):
        monkeypatch.setattr(
            "sarmission.commands.replay.build_detector",
            lambda *_: (ScriptedDetector(script), "scripted detector"),
        )
        report = tmp_path / f"report_{name}"
        code = main(
            [
                "replay",
                str(clip),
                "--mission",
                str(mission_file),
                "--telemetry",
                str(telemetry),
                "--report",
                str(report),
            ]
        )
        out = capsys.readouterr().out
        assert code == 0, out
        assert "alignment: camera trigger 1 of 1" in out, out
        rows = list(csv.DictReader((report / "alerts.csv").open()))
        assert rows, out
        errs = []
        for row in rows:
            lat, lon, err = float(row["lat"]), float(row["lon"]), float(row["error_m"])
            best = min(
                math.hypot(*geodetic_to_ned(lat, lon, 0, t[0], t[1], 0)[:2]) for t in truth.values()
            )
            errs.append((best, err))
        errors[name] = errs
    alignment_error = abs(tlog.triggers[0] - start)
    # the same clip aligned by its creation time alone (whole seconds in an MP4 header)
    by_clock = align_video(
        dataclasses.replace(tlog, triggers=[]), created=creation_time(clip), duration_s=FRAMES / FPS
    )
    clock_error = abs(by_clock.offset_s - start)
    print(
        f"alignment error: tlog trigger vs .BIN trigger {alignment_error * 1e3:.1f} ms, "
        f"creation time vs .BIN trigger {clock_error * 1e3:.0f} ms; position errors (m, "
        f"estimate): {errors}"
    )
    assert alignment_error < 0.25
    assert clock_error <= 0.75
    for errs in errors.values():
        dist = np.array([e for e, _ in errs])
        assert np.median(dist) < GOAL_M, errs
        assert all(e <= max(GOAL_M, 2 * s) for e, s in errs), errs
