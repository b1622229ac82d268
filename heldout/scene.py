"""One held-out clip: its world, flight and camera, rendered frame by frame with ground truth.

:class:`ClipSpec` holds everything drawn from the clip's seed; :class:`ClipRenderer` turns a time
into a BGR frame and the boxes of what it shows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from heldout.bodies import shapes_at
from heldout.camera import Lens, View, block_centres, block_step, ground_points, project, rays
from heldout.geodesy import lat_lon
from heldout.land import LandLook, land_reflectance
from heldout.optics import Sensor, develop, vignette
from heldout.path import DronePath
from heldout.raster import composite, draw_shapes, solid_box
from heldout.sea import Light, SeaLook, foam_pattern, shade_sea, upsample
from heldout.shapes import Shape
from heldout.waves import SEA_STATES, WaveTrains, grid_covering, surface_on_grid
from heldout.world import TARGETS, Thing

#: An object is annotated while at least this share of its coverage is inside the frame.
MIN_VISIBLE_SHARE = 0.3


@dataclass(frozen=True)
class ClipSpec:
    """Everything one clip is made of (all of it drawn from the clip's seed)."""

    seed: int
    kind: str
    lens: Lens
    light: Light
    path: DronePath
    sensor: Sensor
    things: tuple[Thing, ...]
    home: tuple[float, float]
    sea_state: int = 0
    trains: WaveTrains | None = None
    sea: SeaLook | None = None
    land: LandLook | None = None


@dataclass(frozen=True)
class ObjectBox:
    """Ground truth of one object in one frame."""

    track_id: int
    category: str
    bbox: tuple[float, float, float, float]
    visibility: float
    lat: float
    lon: float
    is_target: bool
    posture: str
    speed_m_s: float


class ClipRenderer:
    """Renders the frames of one :class:`ClipSpec`."""

    def __init__(self, spec: ClipSpec) -> None:
        self.spec = spec
        self.step = block_step(spec.lens)
        self._gain = self._auto_exposure() * vignette(
            spec.lens.width, spec.lens.height, spec.sensor.vignette
        )

    def _auto_exposure(self) -> float:
        """Gain that puts the background's median luminance of the first frame at mid-grey."""
        coarse = self._background(self.spec.path.view(0.0), 0.0, full=False)
        luminance = coarse @ np.array([0.07, 0.72, 0.21], np.float32)
        return float(0.22 / max(float(np.median(luminance)), 1e-4))

    def _geometry(self, view: View, full: bool) -> tuple[np.ndarray, ...]:
        lens = self.spec.lens
        u, v = block_centres(lens, self.step)
        ground, ranges = ground_points(lens, view, u, v)
        dirs = rays(lens, view, u, v)
        values = [ground[..., 0], ground[..., 1], ranges, dirs[..., 0], dirs[..., 1], dirs[..., 2]]
        if full:
            values = [upsample(x, lens.width, lens.height) for x in values]
        east, north, ranges, dx, dy, dz = values
        return east, north, ranges, np.stack([dx, dy, dz], axis=-1)

    def _background(self, view: View, t: float, full: bool = True) -> np.ndarray:
        spec = self.spec
        east, north, ranges, dirs = self._geometry(view, full)
        if spec.kind == "sea":
            assert spec.trains is not None and spec.sea is not None
            lens = spec.lens
            cell = view.position[2] / lens.focal_px * (1.0 if full else self.step)
            grid = grid_covering(
                east[::4, ::4], north[::4, ::4], view.heading_deg, cell, int(2.5 * east.size)
            )
            height, slope_e, slope_n = surface_on_grid(spec.trains, grid, t)
            ge, gn = grid.world()
            foam = foam_pattern(ge, gn, spec.sea, t)
            stack = np.dstack([height, slope_e, slope_n, foam]).astype(np.float32)
            col, row = grid.index_of(east, north)
            looked_up = cv2.remap(
                stack,
                col.astype(np.float32),
                row.astype(np.float32),
                cv2.INTER_LINEAR,
                borderMode=cv2.BORDER_REFLECT,
            )
            return shade_sea(
                looked_up[..., 0],
                looked_up[..., 1],
                looked_up[..., 2],
                looked_up[..., 3],
                dirs,
                ranges,
                spec.light,
                spec.sea,
            )
        assert spec.land is not None
        if full:  # the ground texture at half resolution, looked up bilinearly
            half = (east.shape[1] // 2, east.shape[0] // 2)
            reflectance, lit = land_reflectance(
                cv2.resize(east, half, interpolation=cv2.INTER_LINEAR),
                cv2.resize(north, half, interpolation=cv2.INTER_LINEAR),
                spec.land,
                spec.light.sun_azimuth_deg,
            )
            reflectance = cv2.resize(reflectance, east.shape[::-1], interpolation=cv2.INTER_LINEAR)
            lit = cv2.resize(lit, east.shape[::-1], interpolation=cv2.INTER_LINEAR)
        else:
            reflectance, lit = land_reflectance(east, north, spec.land, spec.light.sun_azimuth_deg)
        sun = max(math.sin(math.radians(spec.light.sun_elevation_deg)), 0.05)
        radiance = reflectance * (spec.light.sun_radiance * sun * lit + 0.35)[..., None]
        veil = (1.0 - np.exp(-ranges / spec.light.visibility_m)).astype(np.float32)[..., None]
        return radiance * (1 - veil) + np.array(spec.light.haze_bgr, np.float32) * veil

    def _shapes(
        self, thing: Thing, t: float, heading: float, position: tuple[float, ...]
    ) -> list[Shape]:
        spec = self.spec
        lifted = 0.0
        if spec.trains is not None and position[2] == 0.0:
            hs = SEA_STATES[spec.sea_state][0]
            lifted = float(
                np.clip(
                    spec.trains.height_at(position[0], position[1], t) / max(hs / 2, 0.05), -1, 1
                )
            )
        sun_in_body = spec.light.sun_azimuth_deg - heading
        return shapes_at(thing.look, t, lifted, sun_in_body, spec.light.sun_elevation_deg)

    def render(self, t: float, rng: np.random.Generator) -> tuple[np.ndarray, list[ObjectBox]]:
        """The BGR ``uint8`` frame at ``t`` seconds and the boxes of the objects it shows."""
        spec = self.spec
        lens, view = spec.lens, spec.path.view(t)
        radiance = self._background(view, t)
        placed = [(thing, *thing.place(t)) for thing in spec.things]
        placed.sort(key=lambda p: p[1][2])  # low objects first, birds in flight last
        anchors = np.array([p[1] for p in placed]) if placed else np.zeros((0, 3))
        uv, depth = project(lens, view, anchors)
        margin = 0.3 * lens.width
        boxes: list[ObjectBox] = []
        for (thing, position, heading), (u, v), d in zip(placed, uv, depth, strict=True):
            if not (
                d > 0 and -margin < u < lens.width + margin and -margin < v < lens.height + margin
            ):
                continue
            patch = draw_shapes(
                lens, view, position, heading, self._shapes(thing, t, heading, position)
            )
            if patch is None:
                continue
            composite(radiance, patch)
            found = solid_box(patch, lens.width, lens.height)
            if found is None or found[1] < MIN_VISIBLE_SHARE:
                continue
            lat, lon = lat_lon(spec.home[0], spec.home[1], position[0], position[1])
            boxes.append(
                ObjectBox(
                    thing.track_id,
                    thing.category,
                    found[0],
                    found[1],
                    lat,
                    lon,
                    thing.category in TARGETS,
                    thing.look.posture,
                    math.hypot(*thing.velocity),
                )
            )
        exposure = spec.sensor.exposure_s
        centre = np.array([[lens.width / 2, lens.height / 2]])
        ground_now, _ = ground_points(lens, view, centre[:, 0], centre[:, 1])
        later = spec.path.view(t + exposure)
        moved, _ = project(lens, later, np.array([[*ground_now[0], 0.0]]))
        streak = (float(moved[0, 0] - centre[0, 0]), float(moved[0, 1] - centre[0, 1]))
        return develop(radiance, self._gain, spec.sensor, streak, rng), boxes
