"""Constant-velocity Kalman filter for one tiny box in image space.

Units are pixels and video frames (velocities in px/frame), so the same numbers hold at any
resolution of the clock. State and measurement::

    x = [cx, cy, w, h, vx, vy]^T        box centre, box size, centre velocity
    z = [cx, cy, w, h]^T                one detection

Motion over ``dt`` frames (``F``) and measurement (``H``)::

        | 1 0 0 0 dt 0  |             | 1 0 0 0 0 0 |
        | 0 1 0 0 0  dt |             | 0 1 0 0 0 0 |
    F = | 0 0 1 0 0  0  |         H = | 0 0 1 0 0 0 |
        | 0 0 0 1 0  0  |             | 0 0 0 1 0 0 |
        | 0 0 0 0 1  0  |
        | 0 0 0 0 0  1  |

The size has no velocity of its own. A 3-30 px box changes size only as the altitude changes,
far slower than the detector's size jitter, and a size velocity fitted to that jitter would
extrapolate to shrinking or negative boxes while a track coasts. The size is a random walk instead.

Process noise ``Q``: each centre axis is driven by a white acceleration ``a ~ N(0, sa^2)``
held for ``dt`` (the discrete white-noise-acceleration model), the size by a random walk of
``ss^2`` per frame::

    Q[p, p] = sa^2 dt^4 / 4    Q[p, v] = Q[v, p] = sa^2 dt^3 / 2    Q[v, v] = sa^2 dt^2
    Q[w, w] = Q[h, h] = ss^2 dt

Measurement noise ``R = diag(sp^2, sp^2, sz^2, sz^2)``: the detector's centre and size errors.
Initial covariance ``P0 = diag(sp^2, sp^2, sz^2, sz^2, sv^2, sv^2)``: the first detection fixes
the box, the velocity is unknown up to ``sv`` (the platform can move the image several px/frame).

Camera motion: a swimmer drifts under 1 px/frame, but the platform moves the whole image by
several px/frame. When the image displacement of the ground between two frames is known (from
telemetry or image registration), :meth:`BoxKalman.predict` adds it to the predicted centre.
The velocity then stays the target's own motion over the ground. Without it the velocity absorbs
the platform's (smooth) motion, which the constant-velocity model follows as long as it changes
slowly; ``sa`` leaves room for that.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from filterpy.kalman import KalmanFilter

from sarmission.boxes import cxcywh_to_xyxy, xyxy_to_cxcywh

STATE_DIM = 6
MEASUREMENT_DIM = 4

#: z = H x: the detection measures the centre and the size, not the velocity.
MEASUREMENT_MATRIX = np.hstack([np.eye(MEASUREMENT_DIM), np.zeros((MEASUREMENT_DIM, 2))])


@dataclass(frozen=True)
class MotionNoise:
    """Standard deviations of the filter's noise, in px and frames (defaults for 30 fps video).

    ``position_std`` (sp): detector centre error, about 1 px on boxes 3-30 px wide.
    ``size_std`` (sz): detector width/height error; box regression on tiny boxes jitters more
    than the centre does.
    ``acceleration_std`` (sa): change of image velocity per frame. A drifting swimmer barely
    accelerates; most of this is the platform's motion changing when no camera shift is given.
    ``size_drift_std`` (ss): true size change per frame (altitude changes slowly).
    ``initial_velocity_std`` (sv): velocity uncertainty of a new track; covers the platform
    moving the image several px/frame.
    """

    position_std: float = 1.0
    size_std: float = 1.5
    acceleration_std: float = 0.2
    size_drift_std: float = 0.2
    initial_velocity_std: float = 5.0


def transition_matrix(dt: float) -> np.ndarray:
    """``F(dt)``: centre moves by velocity times ``dt``; size and velocity carry over."""
    f = np.eye(STATE_DIM)
    f[0, 4] = f[1, 5] = dt
    return f


def process_noise(dt: float, noise: MotionNoise) -> np.ndarray:
    """``Q(dt)``: white acceleration on each centre axis, random walk on the size."""
    qa = noise.acceleration_std**2
    q = np.zeros((STATE_DIM, STATE_DIM))
    for p, v in ((0, 4), (1, 5)):
        q[p, p] = qa * dt**4 / 4
        q[p, v] = q[v, p] = qa * dt**3 / 2
        q[v, v] = qa * dt**2
    q[2, 2] = q[3, 3] = noise.size_drift_std**2 * dt
    return q


class BoxKalman:
    """Kalman filter of one track's box, started from its first detection ``[x1, y1, x2, y2]``."""

    def __init__(self, box_xyxy: np.ndarray, noise: MotionNoise | None = None) -> None:
        self.noise = noise or MotionNoise()
        sp2, sz2 = self.noise.position_std**2, self.noise.size_std**2
        self.kf = KalmanFilter(dim_x=STATE_DIM, dim_z=MEASUREMENT_DIM)
        self.kf.F = transition_matrix(1.0)
        self.kf.H = MEASUREMENT_MATRIX.copy()
        self.kf.Q = process_noise(1.0, self.noise)
        self.kf.R = np.diag([sp2, sp2, sz2, sz2])
        self.kf.P = np.diag([sp2, sp2, sz2, sz2] + [self.noise.initial_velocity_std**2] * 2)
        self.kf.x = np.zeros((STATE_DIM, 1))
        self.kf.x[:4, 0] = _measurement(box_xyxy)

    def predict(
        self, dt: float = 1.0, camera_shift: tuple[float, float] | None = None
    ) -> np.ndarray:
        """Advance the state by ``dt`` frames and return the predicted box ``[x1, y1, x2, y2]``.

        ``camera_shift=(dx, dy)`` is how far static ground moved in the image since the last
        frame (px); it is added to the predicted centre and leaves the velocity alone.
        """
        self.kf.predict(F=transition_matrix(dt), Q=process_noise(dt, self.noise))
        if camera_shift is not None:
            self.kf.x[0, 0] += camera_shift[0]
            self.kf.x[1, 0] += camera_shift[1]
        return self.box

    def update(self, box_xyxy: np.ndarray) -> None:
        """Correct the state with a detection ``[x1, y1, x2, y2]``."""
        self.kf.update(_measurement(box_xyxy))

    @property
    def box(self) -> np.ndarray:
        """Current box estimate ``[x1, y1, x2, y2]``."""
        return cxcywh_to_xyxy(self.kf.x[:4, 0])

    @property
    def centre(self) -> tuple[float, float]:
        """Current centre estimate ``(cx, cy)`` in px."""
        return float(self.kf.x[0, 0]), float(self.kf.x[1, 0])

    @property
    def velocity(self) -> tuple[float, float]:
        """Centre velocity ``(vx, vy)`` in px/frame (over the ground when shifts are given)."""
        return float(self.kf.x[4, 0]), float(self.kf.x[5, 0])


def _measurement(box_xyxy: np.ndarray) -> np.ndarray:
    return xyxy_to_cxcywh(np.asarray(box_xyxy, dtype=np.float64).reshape(4))
