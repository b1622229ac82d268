"""The MAVLink vehicle seen by MAVSDK (native in-process binding) over real UDP."""

import math
import threading
import time

import pytest
from conftest import free_udp_port

from sarmission.mission.config import load_mission
from sim.vehicle import SimVehicle

mavsdk = pytest.importorskip("mavsdk")
from mavsdk import ComponentType, Configuration, ConnectionResult, Mavsdk  # noqa: E402
from mavsdk.plugins.mission_raw import MissionItem, MissionRaw  # noqa: E402
from mavsdk.plugins.telemetry import Telemetry  # noqa: E402


def call_with_timeout(fn, timeout_s):
    """Run a blocking MAVSDK call in a thread so a failure fails instead of hanging."""
    box = {}

    def run():
        try:
            box["value"] = fn()
        except Exception as exc:  # re-raised in the test thread
            box["error"] = exc

    th = threading.Thread(target=run, daemon=True)
    th.start()
    th.join(timeout_s)
    if th.is_alive():
        raise AssertionError(f"{getattr(fn, '__name__', fn)} did not return within {timeout_s} s")
    if "error" in box:
        raise box["error"]
    return box["value"]


@pytest.mark.parametrize("vehicle_listens", [True, False])
def test_mavsdk_telemetry_and_mission_round_trip(vehicle_listens):
    mission = load_mission(overrides={"flight.takeoff": False})
    port = free_udp_port()
    if vehicle_listens:  # vehicle udpin, MAVSDK sends to it
        vehicle_url, sdk_url = f"udpin:127.0.0.1:{port}", f"udpout://127.0.0.1:{port}"
    else:  # MAVSDK listens, vehicle sends to it
        vehicle_url, sdk_url = f"udpout:127.0.0.1:{port}", f"udpin://127.0.0.1:{port}"
    sdk = Mavsdk(Configuration.create_with_component_type(ComponentType.GROUND_STATION))
    try:
        with SimVehicle(vehicle_url, mission, seed=4) as vehicle:
            assert sdk.add_any_connection(sdk_url) == ConnectionResult.SUCCESS
            system = call_with_timeout(lambda: sdk.first_autopilot(5.0), 8.0)
            assert system is not None, "MAVSDK saw no autopilot"
            assert system.get_system_id() == 1
            telemetry = Telemetry(system)
            positions = []
            telemetry.subscribe_position(lambda p, _ud=None: positions.append(p))
            deadline = time.monotonic() + 5.0
            while len(positions) < 5 and time.monotonic() < deadline:
                time.sleep(0.05)
            assert len(positions) >= 5, "no position telemetry"
            p = positions[-1]
            home_lat, home_lon, _ = mission.area.home
            assert abs(p.latitude_deg - home_lat) < 0.01 and abs(p.longitude_deg - home_lon) < 0.01
            assert p.relative_altitude_m == pytest.approx(mission.flight.altitude_m, abs=5.0)
            att = call_with_timeout(telemetry.attitude_euler, 3.0)
            truth = vehicle.truth_state()
            yaw_err = (att.yaw_deg - math.degrees(truth.yaw) + 180.0) % 360.0 - 180.0
            assert abs(yaw_err) < 10.0
            assert abs(att.roll_deg) < 30.0 and abs(att.pitch_deg) < 30.0

            mission_raw = MissionRaw(system)
            items = [
                MissionItem(
                    seq=i,
                    frame=6,
                    command=16,
                    current=int(i == 0),
                    autocontinue=1,
                    param2=2.0,
                    x=int(54.17e7) + 900 * i,
                    y=int(7.89e7) + 500 * i,
                    z=40.0 + i,
                    mission_type=0,
                )
                for i in range(3)
            ]
            call_with_timeout(lambda: mission_raw.upload_mission(items), 10.0)
            assert [it.x for it in vehicle.missions[0]] == [it.x for it in items]
            back = call_with_timeout(mission_raw.download_mission, 10.0)
            assert [(b.seq, b.command, b.x, b.y, b.z) for b in back] == [
                (i.seq, i.command, i.x, i.y, i.z) for i in items
            ]
            assert vehicle.is_alive
    finally:
        sdk.destroy()
