"""A flight log into a :class:`~sarmission.mavlink.telemetry.TelemetryBuffer`, as replay
time advances.

The buffer keeps only the last ``max_age_s`` of samples, so the log is pushed in time
order up to the frame being replayed plus :data:`LOOKAHEAD_S` (the interpolation needs the
sample after the frame). Home, the format's accuracies and, per position, the logged GNSS
accuracy go into the buffer with the samples. A log that places images one by one (EXIF)
sets the buffer's staleness limit to a millisecond: an image the log does not place gets no
pose from its neighbours.
"""

from __future__ import annotations

import math

from sarmission.flightlog.model import FlightLog
from sarmission.mavlink.telemetry import MIN_GNSS_SIGMA_M, TelemetryBuffer

#: Seconds of log pushed ahead of the frame being replayed.
LOOKAHEAD_S = 2.0
#: Staleness limit for logs that place each image by itself (seconds).
PER_IMAGE_STALE_S = 1e-3


class LogFeeder:
    """Pushes ``log`` into ``buffer`` (see the module docstring)."""

    def __init__(self, log: FlightLog, buffer: TelemetryBuffer) -> None:
        self.log = log
        self.buffer = buffer
        if log.home is not None:
            buffer.set_home(*log.home)
        acc = log.accuracy
        buffer.gnss_sigma_m = acc.gnss_sigma_m
        buffer.alt_sigma_m = acc.alt_sigma_m
        buffer.attitude_sigma_rad = math.radians(acc.attitude_sigma_deg)
        if log.image_times:
            buffer.stale_after_s = PER_IMAGE_STALE_S
        self._next = {"position": 0, "attitude": 0, "gimbal": 0}
        self.pushed = 0

    def advance(self, t_log: float) -> None:
        """Push every sample up to ``t_log + LOOKAHEAD_S``."""
        until = t_log + LOOKAHEAD_S
        log, buf, nxt = self.log, self.buffer, self._next
        while nxt["position"] < len(log.positions) and log.positions[nxt["position"]].t <= until:
            p = log.positions[nxt["position"]]
            # a logged accuracy of centimetres (RTK) is floored as the live link's is
            buf.gnss_sigma_m = max(p.gnss_sigma_m or log.accuracy.gnss_sigma_m, MIN_GNSS_SIGMA_M)
            buf.push_position(p.t, p.lat, p.lon, p.rel_alt_m, alt_m=p.alt_m)
            nxt["position"] += 1
            self.pushed += 1
        while nxt["attitude"] < len(log.attitudes) and log.attitudes[nxt["attitude"]].t <= until:
            a = log.attitudes[nxt["attitude"]]
            buf.push_attitude_quaternion(a.t, a.q)
            nxt["attitude"] += 1
        while nxt["gimbal"] < len(log.gimbal) and log.gimbal[nxt["gimbal"]].t <= until:
            g = log.gimbal[nxt["gimbal"]]
            buf.push_gimbal(g.t, g.q, g.frame)
            nxt["gimbal"] += 1
