"""The simulated camera: renders the simulated vehicle's flight as it happens.

A live camera: each :meth:`SimCamera.read` renders the scene at the vehicle's current sim time
from its exact camera pose and stamps the frame with the local ``time.monotonic()`` of that
instant, the clock the controller maps the vehicle's MAVLink telemetry to (the vehicle must run
at ``speedup = 1`` for the two to agree). Frames are never queued: a slow reader simply gets
fewer, newer frames. With ``fps`` reads are paced to at most that rate.

The annotations of the people to find are kept per frame (:attr:`SimCamera.truth`) for scoring
a run: which were in view, and where they really were when a frame showed them.
``corrupt_every = n`` delivers every n-th frame cut to half its height, a sensor glitch that the
consumer must skip.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from sarmission.data.frames import Frame
from sarmission.geo.camera import CameraIntrinsics, CameraPose
from sim.render import ObjectAnnotation, SceneRenderer
from sim.scene import Scenario
from sim.vehicle import SimVehicle


class Renderer(Protocol):
    """Anything that renders a frame and its annotations at sim time ``t`` from ``pose``."""

    def render(self, t: float, pose: CameraPose) -> tuple[np.ndarray, list[ObjectAnnotation]]: ...


@dataclass
class FrameTruth:
    """Ground truth of one delivered frame: sim time, the target annotations in view and the
    other objects' (boats, birds, debris, glints)."""

    index: int
    sim_time: float
    targets: list[ObjectAnnotation]
    others: list[ObjectAnnotation] = field(default_factory=list)


def mission_scenario(vehicle: SimVehicle, seed: int | None = None, **kwargs: object) -> Scenario:
    """A maritime scenario over the vehicle's search area (its bounding box in NED metres)."""
    pts = np.asarray(vehicle.mission.area.polygon_ne(), dtype=float)
    area = (
        float(pts[:, 0].min()),
        float(pts[:, 1].min()),
        float(pts[:, 0].max()),
        float(pts[:, 1].max()),
    )
    return Scenario(
        kind="maritime",
        seed=vehicle.seed if seed is None else seed,
        area_ne=area,
        wind_from_deg=vehicle.mission.sim.wind_from_deg,
        **kwargs,
    )


class SimCamera:
    """Camera on a :class:`SimVehicle`.

    Args:
        vehicle: the (started) vehicle whose flight is filmed.
        renderer: a renderer; default a :class:`SceneRenderer` of ``scenario``.
        scenario: the world to render (default :func:`mission_scenario`).
        size: ``(width, height)`` of the frames; default the mission camera's.
        fps: the most frames per second delivered (None: as fast as they are read).
        corrupt_every: deliver every n-th frame truncated (0: never).
    """

    def __init__(
        self,
        vehicle: SimVehicle,
        renderer: Renderer | None = None,
        scenario: Scenario | None = None,
        size: tuple[int, int] | None = None,
        fps: float | None = None,
        corrupt_every: int = 0,
    ) -> None:
        if fps is not None and fps <= 0:
            raise ValueError(f"fps must be positive, got {fps}")
        if corrupt_every < 0:
            raise ValueError(f"corrupt_every must be >= 0, got {corrupt_every}")
        self.vehicle = vehicle
        camera = vehicle.mission.camera.intrinsics()
        self.intrinsics: CameraIntrinsics = camera if size is None else camera.scaled(*size)
        if renderer is None:
            renderer = SceneRenderer(
                scenario or mission_scenario(vehicle), self.intrinsics, home=vehicle.home
            )
        self.renderer = renderer
        self.fps = fps
        self.corrupt_every = corrupt_every
        self.truth: list[FrameTruth] = []
        self.skipped = 0
        self.corrupted = 0
        self._count = 0
        self._next_due = 0.0

    def read(self) -> Frame:
        """Render and return the newest frame (waits while the ``fps`` limit says so)."""
        if self.fps is not None:
            delay = self._next_due - time.monotonic()
            if delay > 0:
                time.sleep(delay)
        stamp = time.monotonic()
        t = self.vehicle.sim_time()
        self._next_due = stamp + (1.0 / self.fps if self.fps else 0.0)
        image, annotations = self.renderer.render(t, self.vehicle.camera_pose(t))
        index = self._count
        self._count += 1
        self.truth.append(
            FrameTruth(
                index,
                t,
                [a for a in annotations if a.is_target],
                [a for a in annotations if not a.is_target],
            )
        )
        if self.corrupt_every and (index + 1) % self.corrupt_every == 0:
            self.corrupted += 1
            image = image[: image.shape[0] // 2]
        return Frame(index, stamp, image)

    def close(self) -> None:
        """Nothing to release (present for the frame-source interface)."""

    def targets_in_view(self) -> dict[int, ObjectAnnotation]:
        """Target track id -> its last annotation, for every target any frame showed."""
        seen: dict[int, ObjectAnnotation] = {}
        for frame in self.truth:
            for a in frame.targets:
                seen[a.track_id] = a
        return seen

    def targets_at(self, frame_index: int) -> list[ObjectAnnotation]:
        """The target annotations of one delivered frame."""
        return self._frame(frame_index).targets

    def others_at(self, frame_index: int) -> list[ObjectAnnotation]:
        """The annotations of the non-target objects (boats, birds, ...) of one delivered frame."""
        return self._frame(frame_index).others

    def _frame(self, frame_index: int) -> FrameTruth:
        if not 0 <= frame_index < len(self.truth):
            raise IndexError(f"no frame {frame_index} (delivered {len(self.truth)})")
        return self.truth[frame_index]
