"""``sarmission sim vehicle``: run one simulated vehicle in the foreground and print its flight."""

from __future__ import annotations

import logging
import math
import time

from sim.vehicle.vehicle import SimVehicle

#: Wall seconds between the printed status lines.
PRINT_EVERY_S = 5.0


def run_vehicle(
    listen: str, mission_path: str | None, speedup: float, seed: int, duration: float | None
) -> int:
    """Run a vehicle until Ctrl-C or ``duration`` seconds of wall time; print what it does."""
    logging.basicConfig(level=logging.INFO, format="%(asctime)s %(levelname)s %(message)s")
    vehicle = SimVehicle(listen, mission_path, speedup=speedup, seed=seed)
    print(
        f"vehicle: mission '{vehicle.mission.name}' on {listen}, speedup {speedup:g}, seed {seed};"
        f" survey takes {vehicle.flight.survey_duration:.0f} s of sim time",
        flush=True,
    )
    deadline = None if duration is None else time.monotonic() + duration
    last_print = 0.0
    try:
        with vehicle:
            while deadline is None or time.monotonic() < deadline:
                time.sleep(0.2)
                if time.monotonic() - last_print >= PRINT_EVERY_S:
                    last_print = time.monotonic()
                    s = vehicle.truth_state()
                    n, e, d = s.position_ned
                    print(
                        f"t={s.t:7.1f}s  NED=({n:7.1f}, {e:7.1f}, {d:6.1f})  "
                        f"yaw={math.degrees(s.yaw):6.1f}  sent={sum(vehicle.sent_counts.values())}"
                        f"  statustexts={len(vehicle.statustexts)}",
                        flush=True,
                    )
    except KeyboardInterrupt:
        print("vehicle: stopped", flush=True)
    return 0
