"""Live runs over real UDP on 127.0.0.1 against the simulated vehicle: alerts, autopilot
commands, crash and restart, link loss, malformed input. The detector is the blob detector on a
scene of white dots (the detector is not under test); MAVLink, telemetry, geolocation, the store
and the controller are the real ones."""

import json
import os
import re
import signal
import socket
import subprocess
import sys
import threading
import time
import urllib.request
import xml.etree.ElementTree as ET
from collections import Counter
from pathlib import Path

import pytest
import run_scripted
from conftest import free_udp_port, wait_until
from dot_scene import DotRenderer
from scripted_detector import BlobDetector

from sarmission.alerts.store import AlertStore
from sarmission.cli import main
from sarmission.mavlink.connection import M
from sarmission.mission.actions import ascii_statustext
from sarmission.mission.config import load_mission
from sarmission.mission.live import LiveSession
from sarmission.mission.targets import distance_m
from sim.camera import SimCamera
from sim.vehicle import SimVehicle

TESTS = Path(__file__).resolve().parent
# One 80 m leg eastwards along north = 20 from east = -40 at 5 m/s; 480x270 frames at 60 deg see
# 81 m across the track and 46 m along it, so a point at east = E comes into view at about
# t = (E + 17) / 5 seconds.
OVERRIDES = {
    "name": "e2e",
    "area.rectangle_m": [0.0, -40.0, 40.0, 40.0],
    "area.leg_spacing_m": 40.0,
    "area.heading_deg": 90.0,
    "flight.takeoff": False,
    "flight.speed_m_s": 5.0,
    "camera.width": 480,
    "camera.height": 270,
    "camera.hfov_deg": 60.0,
}
SET_ARGS = [a for k, v in OVERRIDES.items() for a in ("--set", f"{k}={json.dumps(v)}")]
REPEATS = load_mission().actions.statustext_repeats  # sends of each STATUSTEXT alert


def mission_with(**extra):
    return load_mission(overrides={**OVERRIDES, **extra})


def truth(mission, north, east):
    from sarmission.geo.wgs84 import ned_to_geodetic

    lat, lon, _ = ned_to_geodetic(north, east, 0.0, *mission.area.home)
    return float(lat), float(lon)


def session_for(mission, vehicle, port, db, targets, lines, **camera_kwargs):
    renderer = DotRenderer(targets, mission.camera.intrinsics(), mission.area.home)
    camera = SimCamera(vehicle, renderer=renderer, fps=15.0, **camera_kwargs)
    return LiveSession(
        mission,
        BlobDetector(),
        camera,
        f"udp:127.0.0.1:{port}",
        str(db),
        transport_latency_s=mission.telemetry.latency_s,
        connect_timeout_s=5.0,
        console=lines.append,
    ), camera


def test_targets_alerted_once_loiter_acknowledged_despite_garbage(tmp_path):
    # one visit every 2 s (60 s by default), a group radius below their spacing: each person
    # gets a reposition of their own within the run
    mission = mission_with(
        **{
            "actions.policy": ["alert", "loiter"],
            "actions.visit_interval_s": 2.0,
            "actions.visit_group_radius_m": 5.0,
        }
    )
    targets = [(20.0, 5.0), (30.0, 15.0)]  # 14 m apart: two people
    port = free_udp_port()
    vehicle = SimVehicle(f"udpout:127.0.0.1:{port}", mission, stream_on_request=True).start()
    lines: list[str] = []
    try:
        session, camera = session_for(
            mission, vehicle, port, tmp_path / "alerts.db", targets, lines, corrupt_every=9
        )
        stop_noise = threading.Event()

        def garbage() -> None:  # malformed MAVLink at the controller's port
            with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as s:
                while not stop_noise.wait(0.1):
                    s.sendto(
                        b"\xfd\x09\x00\x00\x07\x01\x01\x00\x00\x00garbage!!\x00",
                        ("127.0.0.1", port),
                    )
                    s.sendto(os.urandom(40), ("127.0.0.1", port))

        noise = threading.Thread(target=garbage, daemon=True)
        noise.start()
        try:
            session.run(duration_s=11.0)
        finally:
            stop_noise.set()
            noise.join()
            summary = session.close()
            bad_after_close = session.link.bad_packets
    finally:
        vehicle.stop()
    with AlertStore(tmp_path / "alerts.db") as store:
        alerts = store.list()
    assert len(alerts) == 2, "\n".join(lines)
    for alert, (n, e) in zip(sorted(alerts, key=lambda a: a.position[1]), targets, strict=True):
        assert distance_m(alert.position, truth(mission, n, e)) < 5.0
        assert set(alert.delivered) == {"mavlink_loiter"}  # acknowledged
        assert alert.sent["mavlink"].count >= 1  # STATUSTEXT: sent, nothing acknowledges it
    # every send the store counts reached the vehicle (no loss on 127.0.0.1)
    assert Counter(s.text for s in vehicle.statustexts) == {
        a.statustext().replace("±", "+-"): a.sent["mavlink"].count for a in alerts
    }
    repositions = [c for c in vehicle.commands if c.command == M.MAV_CMD_DO_REPOSITION]
    # one reposition per target; a COMMAND_INT whose ACK came late is re-sent unchanged
    assert len({c.params[4:6] for c in repositions}) == 2
    assert all(c.is_int and c.result == M.MAV_RESULT_ACCEPTED for c in repositions)
    assert sum("ALERT target" in line for line in lines) == 2
    # the receiver keeps reading queued garbage until the link closes, after the summary
    reported = re.search(r"(\d+) malformed skipped", summary)
    assert reported is not None, summary
    assert 0 < int(reported.group(1)) <= bad_after_close
    assert camera.corrupted > 0 and "size 480x135 differs" in summary


def test_killed_and_restarted_run_loses_and_repeats_nothing(tmp_path):
    port = free_udp_port()
    db = tmp_path / "alerts.db"
    targets = json.dumps([[20.0, 0.0], [20.0, 30.0]])
    cmd = [
        sys.executable,
        str(TESTS / "run_scripted.py"),
        targets,
        "--connect",
        f"udp:127.0.0.1:{port}",
        "--sim",
        "--sim-fps",
        "15",
        "--alerts-db",
        str(db),
        "--connect-timeout",
        "5",
        *SET_ARGS,
    ]
    env = {**os.environ, "PYTHONUNBUFFERED": "1"}
    first = subprocess.Popen(
        [*cmd, "--duration", "30"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=env
    )
    try:
        deadline = time.monotonic() + 40
        while time.monotonic() < deadline and first.poll() is None:
            if db.exists():
                with AlertStore(db) as store:
                    if store.count() >= 1:
                        break
            time.sleep(0.1)
        first.kill()  # SIGKILL right after the first confirmed alert
        first.wait(10)
    finally:
        if first.poll() is None:
            first.kill()
    with AlertStore(db) as store:
        before = store.list()
    assert len(before) == 1, first.stdout.read().decode()

    second = subprocess.Popen(
        [*cmd, "--duration", "40"], stdout=subprocess.PIPE, stderr=subprocess.STDOUT, env=env
    )
    try:
        deadline = time.monotonic() + 40
        done = False
        while time.monotonic() < deadline and second.poll() is None and not done:
            time.sleep(0.2)
            with AlertStore(db) as store:
                alerts = store.list()
                done = len(alerts) >= 2 and not store.undelivered("mavlink", REPEATS)
        second.send_signal(signal.SIGINT)  # clean stop: summary and exit code 0
        out, _ = second.communicate(timeout=20)
    finally:
        if second.poll() is None:
            second.kill()
    text = out.decode()
    assert second.returncode == 0, text
    assert "1 target(s) already alerted" in text
    assert "frames processed:" in text
    with AlertStore(db) as store:
        alerts = store.list()
        assert store.undelivered("mavlink", REPEATS) == []  # the killed run's sends resumed
    assert [a.alert_id for a in alerts[:1]] == [before[0].alert_id]
    assert len(alerts) == 2 and len({a.target_id for a in alerts}) == 2, text
    mission = mission_with()
    found = sorted(alerts, key=lambda a: a.position[1])
    assert distance_m(found[0].position, truth(mission, 20.0, 0.0)) < 5.0
    assert distance_m(found[1].position, truth(mission, 20.0, 30.0)) < 5.0


def test_alert_during_link_loss_is_delivered_after(tmp_path):
    # a second of evidence (the default is two): the rebooted autopilot is back for four
    mission = mission_with(**{"confirm.min_seen_s": 1.0, "confirm.min_sightings": 6})
    port = free_udp_port()
    vehicle = SimVehicle(f"udpout:127.0.0.1:{port}", mission, stream_on_request=True).start()
    lines: list[str] = []
    try:
        session, _ = session_for(
            mission, vehicle, port, tmp_path / "alerts.db", [(20.0, 10.0)], lines
        )

        def locked() -> bool:
            return any(line.startswith("CANDIDATE target 1") for line in list(lines))

        def outage() -> None:
            # silent once the session believes the autopilot's telemetry, before the lock
            wait_until(
                lambda: session.telemetry.newest_time("position") is not None or locked(), 15.0
            )
            vehicle.stop()
            wait_until(locked, 15.0)  # the lock comes while the autopilot is silent
            vehicle.start()  # same port; its clock restarts like a rebooted autopilot

        cut = threading.Thread(target=outage)
        cut.start()
        try:
            session.run(duration_s=20.0)
        finally:
            cut.join()
            summary = session.close()
    finally:
        vehicle.stop()
    with AlertStore(tmp_path / "alerts.db") as store:
        stored = store.list()
    # locked while the autopilot was silent: a candidate without a position (the operator
    # sees it); once the rebooted autopilot's telemetry places the person again (the flight
    # starts over, so a new target) it is confirmed, and only then told to the autopilot
    assert any(
        line.startswith("CANDIDATE target 1") and "no position for" in line for line in lines
    ), lines
    (alert,) = [a for a in stored if a.tier == "confirmed"]
    assert [a.position for a in stored if a.tier == "candidate"] in ([], [None])
    assert session.telemetry.resets == 1  # the reboot dropped what came before
    assert alert.position is not None
    assert distance_m(alert.position, truth(mission, 20.0, 10.0)) < 5.0
    assert "mavlink" not in alert.delivered  # STATUSTEXT: sent, nothing acknowledges it
    texts = [s.text for s in vehicle.statustexts]
    assert set(texts) == {ascii_statustext(alert)}
    assert 1 <= len(texts) <= alert.sent["mavlink"].count
    assert any(line.startswith("link lost") for line in lines), lines
    assert any(line.startswith("link back") for line in lines), lines
    assert "confirmed alerts: 1" in summary


def free_tcp_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_run_serves_its_alerts_on_the_feed(tmp_path):
    """``run --feed --cot``: the alert confirmed by the run is on the JSON-lines stream as it
    is stored, on the JSON API as it is in the store, and at the team's TAK (a UDP socket
    standing in for it) as a CoT marker whose latest event is at the stored position; the
    mission's own ``[alerts] cot`` destination gets it as well."""
    port, feed_port = free_udp_port(), free_tcp_port()
    db = tmp_path / "alerts.db"
    tak = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    tak.bind(("127.0.0.1", 0))
    mission_tak = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    mission_tak.bind(("127.0.0.1", 0))
    mission_url = f"udp://127.0.0.1:{mission_tak.getsockname()[1]}"
    argv = [
        json.dumps([[20.0, -25.0]]),
        "--connect",
        f"udp:127.0.0.1:{port}",
        "--sim",
        "--sim-fps",
        "15",
        "--alerts-db",
        str(db),
        "--connect-timeout",
        "5",
        "--feed",
        f"127.0.0.1:{feed_port}",
        "--cot",
        f"udp://127.0.0.1:{tak.getsockname()[1]}",
        "--duration",
        "4",
        *SET_ARGS,
        "--set",
        f"alerts.cot={json.dumps([mission_url])}",
    ]
    outcome: list[int] = []
    runner = threading.Thread(target=lambda: outcome.append(run_scripted.main(argv)))
    runner.start()
    base = f"http://127.0.0.1:{feed_port}"
    try:
        deadline = time.monotonic() + 15
        while True:  # the feed starts once the link is up
            try:
                urllib.request.urlopen(base + "/healthz", timeout=1).close()
                break
            except OSError:
                assert time.monotonic() < deadline and runner.is_alive(), "no feed"
                time.sleep(0.1)
        with urllib.request.urlopen(base + "/alerts.jsonl?follow=1", timeout=10) as stream:
            # blocks until the run stores an alert: a candidate first, written again when its
            # position is attached (locked before the first position arrived) and when the
            # evidence confirms it: wait for that line
            streamed = json.loads(stream.readline())
            while streamed["tier"] != "confirmed":
                streamed = json.loads(stream.readline())
        with urllib.request.urlopen(base + "/api/alerts", timeout=5) as r:
            (listed,) = json.loads(r.read())
    finally:
        runner.join(30)
    assert outcome == [0]
    with AlertStore(db) as store:
        (stored,) = store.list()
    assert streamed["alert_id"] == listed["alert_id"] == stored.alert_id
    changing = ("delivered", "refused", "sent")  # may have come in between the reads
    for served in (streamed, listed):
        assert {k: v for k, v in served.items() if k not in changing} == {
            k: v for k, v in stored.to_json_dict().items() if k not in changing
        }
    assert distance_m(stored.position, truth(mission_with(), 20.0, -25.0)) < 5.0
    markers = {}
    for name, receiver in (("cli", tak), ("mission", mission_tak)):
        receiver.settimeout(0.5)
        events = []
        with receiver:
            while True:
                try:
                    events.append(ET.fromstring(receiver.recv(65536)))
                except TimeoutError:
                    break
        markers[name] = [e for e in events if e.get("uid") == stored.cot_uid]
        assert markers[name], (name, [e.get("uid") for e in events])
        latest = markers[name][-1].find("point")
        assert (float(latest.get("lat")), float(latest.get("lon"))) == stored.position
    # one record per event, however many destinations took it
    assert stored.sent["cot"].count == len(markers["cli"]) == len(markers["mission"])


def test_cli_run_sim_with_mitenet(tmp_path, capsys):
    port = free_udp_port()
    code = main(
        [
            "run",
            "--connect",
            f"udp:127.0.0.1:{port}",
            "--sim",
            "--sim-size",
            "320x180",
            "--max-frames",
            "15",
            "--alerts-db",
            str(tmp_path / "a.db"),
            "--connect-timeout",
            "5",
            *SET_ARGS,
        ]
    )
    out = capsys.readouterr().out
    assert code == 0, out
    assert "autopilot 1/1 adopted" in out
    assert "frames processed: 15" in out
    assert "model:" in out


def test_cli_run_reports_a_bad_connection_string(tmp_path, capsys):
    code = main(
        ["run", "--connect", "tcp:127.0.0.1:1", "--sim", "--alerts-db", str(tmp_path / "a.db")]
    )
    assert code == 2
    assert "--sim needs a udp:" in capsys.readouterr().err


@pytest.mark.parametrize("text", ["", "0" * 64])
def test_signing_key_file_forms(tmp_path, text):
    from sarmission.commands.live_options import read_signing_key

    path = tmp_path / "key"
    path.write_text(text)
    if not text:
        with pytest.raises(ValueError):
            read_signing_key(str(path))
    else:
        assert read_signing_key(str(path)) == bytes(32)
