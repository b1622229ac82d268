"""A sender impersonating the autopilot (its own system/component ids, which the source filter
cannot tell apart without signing) injects absurd telemetry and time jumps over real UDP while
the simulated vehicle streams: nothing it says moves the pose, nothing is reset, nothing
crashes; each message is counted as rejected."""

import math
import time

import pymap3d
from conftest import free_udp_port, wait_until
from link_peers import RawPeer

from sarmission.mavlink.connection import MavlinkLink
from sarmission.mavlink.telemetry import MESSAGE_TYPES
from sarmission.mission.config import load_mission
from sarmission.mission.live import stream_rates, telemetry_buffer
from sim.vehicle import SimVehicle

OFF_TIMELINE = "GLOBAL_POSITION_INT: time_boot_ms off the sender's timeline"


def metres(a, b) -> float:
    n, e, _ = pymap3d.geodetic2ned(a[0], a[1], 0.0, b[0], b[1], 0.0)
    return math.hypot(n, e)


def test_an_impersonator_cannot_move_the_pose_or_reset_the_buffer():
    mission = load_mission(overrides={"flight.takeoff": False})
    port = free_udp_port()
    newest: list = []
    with (
        SimVehicle(f"udpout:127.0.0.1:{port}", mission, stream_on_request=True).start(),
        MavlinkLink(f"udpin:127.0.0.1:{port}") as link,
    ):
        buf = telemetry_buffer(mission)
        link.subscribe_autopilot(buf.handle_message, MESSAGE_TYPES)
        link.subscribe(lambda m, t: newest.append(m), ["GLOBAL_POSITION_INT"])
        assert link.wait_autopilot(10.0)
        link.request_streams(stream_rates(mission))
        assert wait_until(
            lambda: buf.latest_position() is not None and buf.home is not None, 15.0
        ), dict(buf.rejected)
        before = buf.latest_position()
        # 4 s of the vehicle's own clock, so that a forgery can claim a boot time long before
        assert wait_until(lambda: newest[-1].time_boot_ms > 4000, 15.0)
        boot_ms = newest[-1].time_boot_ms
        far = (before[0] + 0.01, before[1])  # 1.1 km north
        forger = RawPeer(port, 1, 1, heartbeat=False)  # the autopilot's own ids
        mav = forger.conn.mav
        try:

            def position(ms: int, lat: float, lon: float):
                return mav.global_position_int_encode(
                    ms, round(lat * 1e7), round(lon * 1e7), 60000, 60000, 0, 0, 0, 0
                )

            for k in range(20):  # 2 s of forgeries between the vehicle's own samples
                forger.send(position(boot_ms + 1_000_000 + 100 * k, *far))  # 1000 s ahead
                forger.send(position(boot_ms - 3000 + 100 * k, *far))  # 3 s back
                forger.send(position(boot_ms + 100 * k, 214.7, far[1]))  # off the planet
                forger.send(
                    mav.mount_orientation_encode(boot_ms + 100 * k, math.nan, -90.0, 0.0, math.inf)
                )
                forger.send(mav.attitude_encode(boot_ms + 100 * k, math.inf, 0.0, 0.0, 0, 0, 0))
                time.sleep(0.1)

            def counted() -> bool:
                r = dict(buf.rejected)
                return (
                    r.get(OFF_TIMELINE, 0) >= 40
                    and r.get("GLOBAL_POSITION_INT: lat N out of range", 0) >= 20
                    and r.get("MOUNT_ORIENTATION: mount angles not finite", 0) >= 20
                    and r.get("ATTITUDE: attitude not finite", 0) >= 20
                )

            assert wait_until(counted, 10.0), dict(buf.rejected)
            after = buf.latest_position()
            assert metres(after, before) < 100.0  # the vehicle flew on; the forgeries did not
            assert metres(after, far) > 1000.0
            assert buf.resets == 0 and buf.clock.reboots == 0
            assert buf.home is not None
            pose = buf.lookup(buf.newest_time("position"))
            assert not isinstance(pose, str) and pose.finite()
        finally:
            forger.close()
