"""Render a scenario's world from a camera pose: a BGR frame and exact per-object annotations.

Pipeline for one frame (pinhole camera, no distortion):

1. Background: the sea (:class:`sim.sea.SeaSurface`, quarter resolution) or the city
   (:class:`sim.ground.UrbanGround`, half resolution) through the ground-to-image homography,
   upsampled with ``cv2.resize``; full-resolution grain and sensor noise from
   :class:`sim.sensor.DetailOverlay`; sun-glint sparkles at sea.
2. Objects, far to near (birds last): each is drawn in a small patch through the homography of its
   own plane ``down = -height`` composed with its local-to-world transform, then its upright
   parts, if any, on a billboard facing the camera (:mod:`sim.billboard`).
3. Annotations: the tight box of the projected outline of the object's ``in_box`` parts (flat and
   upright), clipped to the frame; objects whose box lies wholly outside are dropped.

Boxes are in COCO pixel-edge coordinates (the image spans ``[0, width] x [0, height]``; a point at
camera pixel coordinate ``u`` - pixel centres at integers - lies at ``x = u + 0.5``).
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from sarmission.geo.camera import CameraIntrinsics, CameraPose
from sim.billboard import billboard_for, billboard_homography, billboard_parts
from sim.ground import PaintedGround, UrbanGround
from sim.scene import (
    CATEGORIES,
    TARGET_CATEGORIES,
    ObjectState,
    Part,
    Scenario,
    SceneObject,
    World,
    build_world,
)
from sim.sea import SeaSurface
from sim.sensor import DetailOverlay
from sim.sprites import draw_parts, tight_extent
from sim.truth_camera import ground_homography, project
from sim.truth_frames import ned_to_geodetic
from sim.upright_world import build_upright_world
from sim.wild import WildGround


@dataclass
class ObjectAnnotation:
    """Ground truth of one object in one frame.

    ``bbox_xyxy`` in COCO pixel-edge coordinates (see the module docstring), clipped to the frame;
    ``area`` its area in px^2; ``visibility`` = how much of the object shows (waves washing over
    a swimmer) times the share of its unclipped box inside the frame. ``position_ned`` is the
    object's centre (on the sea or ground plane, or in the air for birds); ``lat``/``lon`` its
    geodetic position when the renderer has a home.
    """

    track_id: int
    category: str
    category_id: int
    is_target: bool
    bbox_xyxy: tuple[float, float, float, float]
    area: float
    visibility: float
    position_ned: tuple[float, float, float]
    lat: float | None = None
    lon: float | None = None


class SceneRenderer:
    """Deterministic renderer of one :class:`Scenario` for one camera.

    ``home`` = ``(lat_deg, lon_deg, alt_m)`` of the NED origin adds lat/lon to the annotations.
    ``world`` replaces the objects :func:`sim.scene.build_world` (or, for ``figures =
    "upright"``, :func:`sim.upright_world.build_upright_world`) would place (hand-built scenes).
    Expensive state (wave tiles, city texture, detail tiles) is built once here.
    """

    def __init__(
        self,
        scenario: Scenario,
        intrinsics: CameraIntrinsics,
        home: tuple[float, float, float] | None = None,
        world: World | None = None,
    ) -> None:
        if intrinsics.distortion and any(intrinsics.distortion):
            raise ValueError(
                "SceneRenderer renders an ideal pinhole camera; distortion is not supported"
            )
        self.scenario = scenario
        self.intrinsics = intrinsics
        self.home = home
        if world is None:
            world = (
                build_upright_world(scenario)
                if scenario.figures == "upright"
                else build_world(scenario)
            )
        self.world = world
        self._objects = [o for o in self.world.objects if not o.static]
        self._static = [o.state_at(0.0) for o in self.world.objects if o.static]
        w, h = intrinsics.width, intrinsics.height
        self.sea: SeaSurface | None = None
        self.ground: PaintedGround | None = None
        if scenario.kind == "maritime":
            self.sea = SeaSurface(scenario)
            ss = scenario.sea_state
            self.detail = DetailOverlay(
                w,
                h,
                scenario.seed,
                grain_std=2.0 + 0.6 * ss,
                noise_std=1.6,
                grain_tint=(1.0, 0.95, 0.8),
                drift_px_s=(3.0, 2.0),
            )
        else:
            painter = WildGround if scenario.kind == "wild" else UrbanGround
            self.ground = painter(self.world)
            self.detail = DetailOverlay(
                w, h, scenario.seed, grain_std=2.5, noise_std=1.6, grain_sigma_px=0.6
            )

    def render(self, t: float, pose: CameraPose) -> tuple[np.ndarray, list[ObjectAnnotation]]:
        """Frame (BGR uint8, H x W x 3) and annotations at time ``t`` seen from ``pose``."""
        intr = self.intrinsics
        h_ground = ground_homography(intr, pose)
        frame = self._background(t, pose, h_ground)
        states = [o.state_at(t) for o in self._in_view(t, pose)]
        if self.scenario.figures == "upright":  # far to near, so near objects hide far ones
            states.sort(key=lambda s: -float(np.linalg.norm(s.position_ned - pose.position_ned)))
        states.sort(key=lambda s: -s.position_ned[2] if s.position_ned[2] < 0 else 0.0)
        annotations = []
        for state, painted in [(s, True) for s in self._static] + [(s, False) for s in states]:
            h_obj = self._object_homography(pose, state)
            upright = self._upright(pose, state)
            if not painted:
                draw_parts(frame, h_obj, state.parts, state.visibility)
                if upright is not None:
                    draw_parts(frame, *upright, state.visibility)
            ann = self._annotate(state, h_obj, upright)
            if ann is not None:
                annotations.append(ann)
        annotations.sort(key=lambda a: a.track_id)
        if self.home is not None and annotations:
            ned = np.array([a.position_ned for a in annotations])
            lat, lon, _ = ned_to_geodetic(ned[:, 0], ned[:, 1], ned[:, 2], *self.home)
            for a, la, lo in zip(annotations, np.atleast_1d(lat), np.atleast_1d(lon), strict=True):
                a.lat, a.lon = float(la), float(lo)
        return frame, annotations

    def _in_view(self, t: float, pose: CameraPose) -> list[SceneObject]:
        """Moving objects whose bounding circle may reach into the frame (a cheap cull)."""
        if not self._objects:
            return []
        centres = np.array([o.position_at(t) for o in self._objects])
        radii = np.array([o.radius_m for o in self._objects])
        uv, in_front = project(self.intrinsics, pose, centres)
        depth = (centres - pose.position_ned) @ pose.rotation_ned_from_camera[:, 2]
        reach = radii * self.intrinsics.fx / np.maximum(depth, 1e-6) + 4.0
        w, h = self.intrinsics.width, self.intrinsics.height
        with np.errstate(invalid="ignore"):
            keep = (
                in_front
                & (uv[:, 0] > -reach)
                & (uv[:, 0] < w + reach)
                & (uv[:, 1] > -reach)
                & (uv[:, 1] < h + reach)
            )
        return [o for o, k in zip(self._objects, keep, strict=True) if k]

    def _background(self, t: float, pose: CameraPose, h_ground: np.ndarray) -> np.ndarray:
        intr = self.intrinsics
        if self.sea is not None:
            low, glint = self.sea.render_lowres(intr, pose, h_ground, t, self.detail.mean)
            frame = cv2.resize(low, (intr.width, intr.height), interpolation=cv2.INTER_LINEAR)
        else:
            assert self.ground is not None
            frame = self.ground.render(h_ground, intr.width, intr.height)
            cv2.subtract(frame, (self.detail.mean,) * 3 + (0.0,), dst=frame)
        self.detail.apply(frame, _ground_origin_px(h_ground, intr), t)
        if self.sea is not None:
            self.sea.add_sparkles(frame, glint, t, self.scenario.seed)
        return frame

    def _object_homography(self, pose: CameraPose, state: ObjectState) -> np.ndarray:
        h_plane = ground_homography(self.intrinsics, pose, ground_down=float(state.position_ned[2]))
        return h_plane @ state.local_to_ne()

    def _upright(
        self, pose: CameraPose, state: ObjectState
    ) -> tuple[np.ndarray, list[Part]] | None:
        """Billboard homography and parts of the object's upright parts (None without any)."""
        if not state.upright:
            return None
        board = billboard_for(pose.position_ned, state.position_ned, state.heading)
        if board is None:
            return None
        return (
            billboard_homography(self.intrinsics, pose, board),
            billboard_parts(state.upright, board),
        )

    def _annotate(
        self,
        state: ObjectState,
        h_obj: np.ndarray,
        upright: tuple[np.ndarray, list[Part]] | None = None,
    ) -> ObjectAnnotation | None:
        ext = tight_extent(h_obj, state.parts, state.visibility)
        if upright is not None:
            standing = tight_extent(*upright, state.visibility)
            if ext is None or standing is None:
                ext = standing if ext is None else ext
            else:
                ext = np.concatenate(
                    [np.minimum(ext[:2], standing[:2]), np.maximum(ext[2:], standing[2:])]
                )
        if ext is None:
            return None
        x0, y0, x1, y1 = (float(v) + 0.5 for v in ext)
        w, h = self.intrinsics.width, self.intrinsics.height
        cx0, cy0, cx1, cy1 = max(x0, 0.0), max(y0, 0.0), min(x1, float(w)), min(y1, float(h))
        if cx1 <= cx0 or cy1 <= cy0:
            return None
        full = max((x1 - x0) * (y1 - y0), 1e-9)
        area = (cx1 - cx0) * (cy1 - cy0)
        pos = tuple(float(v) for v in state.position_ned)
        return ObjectAnnotation(
            state.track_id,
            state.category,
            CATEGORIES[state.category],
            state.category in TARGET_CATEGORIES,
            (cx0, cy0, cx1, cy1),
            area,
            float(state.visibility) * area / full,
            pos,
        )


def _ground_origin_px(h_ground: np.ndarray, intr: CameraIntrinsics) -> tuple[float, float]:
    """Image position of the ground origin, extrapolated linearly from the image centre.

    Exact for a translating nadir camera and well defined when the origin itself is far outside
    the view (or beyond the horizon).
    """
    centre = np.array([(intr.width - 1) / 2.0, (intr.height - 1) / 2.0, 1.0])
    g = np.linalg.solve(h_ground, centre)
    if abs(g[2]) < 1e-12:
        return 0.0, 0.0
    g = g[:2] / g[2]

    def px(n: float, e: float) -> np.ndarray:
        p = h_ground @ np.array([n, e, 1.0])
        return p[:2] / p[2]

    base = px(*g)
    jac = np.column_stack([px(g[0] + 1.0, g[1]) - base, px(g[0], g[1] + 1.0) - base])
    origin = base - jac @ g
    if not np.all(np.isfinite(origin)):
        return 0.0, 0.0
    return float(origin[0]), float(origin[1])
