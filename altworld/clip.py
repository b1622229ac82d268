"""One clip of the alternative world: a flight, a background, figures that move, and the boxes.

:func:`render_clip` draws everything from one seed: the camera's path (:class:`Flight`), the sea
or the land, the figures and the camera's optics, writes the video and returns the COCO image
and annotation entries.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from altworld.camera import View, local_affine, off_nadir_deg, project
from altworld.canvas import Canvas, place
from altworld.effects import Optics
from altworld.encode import ClipWriter
from altworld.figures import KINDS, draw, new_look
from altworld.terrain import draw_land
from altworld.water import Sea

WIDTH, HEIGHT, FPS = 1920, 1080, 30.0
#: Finest canvas per figure, in canvas pixels across, so a low pass does not draw huge canvases.
MAX_CANVAS = 260
#: world -> kind -> (least, most) figures per clip.
CASTS: dict[str, dict[str, tuple[int, int]]] = {
    "sea": {
        "swimmer": (1, 5), "jacket": (0, 3), "debris": (2, 8), "weed": (0, 4), "foam": (2, 10),
        "buoy": (0, 2), "ring": (0, 1), "gull": (0, 3), "boat": (0, 1),
    },
    "land": {"person": (2, 6), "animal": (0, 4)},
}  # fmt: skip


@dataclass(frozen=True)
class Flight:
    """The drone's straight path and the camera's attitude over a clip."""

    height: float
    hfov: float
    tilt: float
    heading: float
    velocity: tuple[float, float]
    yaw_rate: float
    wobble: float
    climb: float

    @classmethod
    def draw(cls, rng: np.random.Generator) -> Flight:
        heading = float(rng.uniform(0, 360))
        speed = 0.0 if rng.random() < 0.25 else float(rng.uniform(1, 8))
        course = math.radians(heading + rng.normal(0, 25))
        return cls(
            height=float(np.exp(rng.uniform(math.log(50.0), math.log(200.0)))),
            hfov=float(rng.uniform(55, 90)),
            tilt=float(rng.uniform(0, 8) if rng.random() < 0.5 else rng.uniform(8, 35)),
            heading=heading,
            velocity=(speed * math.sin(course), speed * math.cos(course)),
            yaw_rate=float(rng.uniform(-2, 2)),
            wobble=float(rng.uniform(0.05, 0.4)),
            climb=float(rng.uniform(-1, 1)),
        )

    def view(self, t: float) -> View:
        return View(
            east=self.velocity[0] * t,
            north=self.velocity[1] * t,
            height=self.height + self.climb * t,
            heading_deg=self.heading + self.yaw_rate * t,
            tilt_deg=self.tilt + self.wobble * math.sin(7.1 * t),
            roll_deg=self.wobble * math.sin(9.3 * t + 1.0),
            hfov_deg=self.hfov,
            width=WIDTH,
            height_px=HEIGHT,
        )


def footprint(view: View, margin: float = 0.0) -> tuple[float, float, float, float]:
    """Ground bounds (east min, north min, east max, north max) of the view's corners."""
    inverse = np.linalg.inv(view.homography())
    corners = np.array(
        [[0, 0, 1], [view.width, 0, 1], [view.width, view.height_px, 1], [0, view.height_px, 1]],
        float,
    )
    g = corners @ inverse.T
    g = g[:, :2] / g[:, 2:3]
    return (
        g[:, 0].min() - margin,
        g[:, 1].min() - margin,
        g[:, 0].max() + margin,
        g[:, 1].max() + margin,
    )


@dataclass
class Figure:
    """A figure's look, start and velocity on the ground (metres, m/s)."""

    look: dict
    start: tuple[float, float]
    velocity: tuple[float, float]
    heading: float
    track_id: int
    boxes: int = field(default=0)

    def at(self, t: float) -> tuple[float, float]:
        return self.start[0] + self.velocity[0] * t, self.start[1] + self.velocity[1] * t


def cast(rng: np.random.Generator, world: str, area, colour) -> list[Figure]:
    """The clip's figures, placed uniformly in ``area`` with the world's motions."""
    current = rng.uniform(0, 0.5) * np.array(
        [math.cos(a := rng.uniform(0, 2 * math.pi)), math.sin(a)]
    )
    figures: list[Figure] = []
    for kind, (low, high) in CASTS[world].items():
        for _ in range(int(rng.integers(low, high + 1))):
            look = new_look(rng, kind, colour)
            heading = float(rng.uniform(0, 360))
            own = 0.0
            if kind in ("swimmer", "jacket") and look["pose"] == "stroke":
                own = rng.uniform(0.3, 0.8)
            elif kind == "person" and look["pose"] == "walk":
                own = rng.uniform(0.8, 1.5)
            elif kind == "boat":
                own = rng.uniform(1.5, 6.0)
            elif kind == "gull" and look["flying"]:
                own = rng.uniform(6, 12)
            elif kind == "animal":
                own = rng.uniform(0, 0.4)
            drift = (
                current
                if world == "sea"
                and kind not in ("boat",)
                and not (kind == "gull" and look["flying"])
                else 0 * current
            )
            v = (
                own * np.array([math.sin(math.radians(heading)), math.cos(math.radians(heading))])
                + drift
            )
            start = (float(rng.uniform(area[0], area[2])), float(rng.uniform(area[1], area[3])))
            figures.append(
                Figure(look, start, (float(v[0]), float(v[1])), heading, len(figures) + 1)
            )
    return figures


def render_clip(seed: int, world: str, frames: int, video: Path) -> tuple[list[dict], list[dict]]:
    """Render one clip to ``video``; its images (``frame_index``, ``file_name``) and annotations
    (``frame_index``, ``track_id``, ``category``, ``bbox``), ids not yet assigned."""
    rng = np.random.default_rng(seed)
    flight = Flight.draw(rng)
    first, last = flight.view(0.0), flight.view((frames - 1) / FPS)
    a, b = footprint(first, 5.0), footprint(last, 5.0)
    bounds = (min(a[0], b[0]), min(a[1], b[1]), max(a[2], b[2]), max(a[3], b[3]))
    sun_deg = float(rng.uniform(0, 360))
    gsd = 2 * flight.height * math.tan(math.radians(flight.hfov) / 2) / 3840
    if world == "sea":
        sea = Sea.draw(rng)
        colour = tuple(float(c) for c in sea.colour)
        background = lambda view, t: sea.render(view, t)  # noqa: E731
    else:
        span = max(bounds[2] - bounds[0], bounds[3] - bounds[1])
        land = draw_land(rng, bounds, max(gsd * 0.66, span / 5000), sun_deg)
        colour = land.base
        background = lambda view, t: land.render(view)  # noqa: E731
    inner = footprint(first, -3.0)
    figures = cast(rng, world, inner, colour)
    optics = Optics.draw(rng)
    writer = ClipWriter(video, WIDTH, HEIGHT, FPS, int(rng.integers(17, 27)))
    images, annotations = [], []
    try:
        for index in range(frames):
            t = index / FPS
            view = flight.view(t)
            h = view.homography()
            frame = background(view, t)
            for fig in figures:
                box = _draw_figure(frame, fig, view, h, t, rng, sun_deg)
                category = KINDS[fig.look["kind"]][1]
                if box is not None and category is not None:
                    annotations.append(
                        {
                            "frame_index": index,
                            "track_id": fig.track_id,
                            "category": category,
                            "bbox": box,
                        }
                    )
            writer.write(optics.apply(frame, rng))
            images.append({"frame_index": index, "file_name": f"{video.stem}/{index:06d}.jpg"})
    finally:
        writer.close()
    return images, annotations


def _draw_figure(frame, fig: Figure, view: View, h, t: float, rng, sun_deg: float):
    east, north = fig.at(t)
    u, v = project(h, east, north)
    extent = KINDS[fig.look["kind"]][0]
    jac = local_affine(h, east, north)
    ppm = float(np.linalg.svd(jac, compute_uv=False).max())
    reach = extent * ppm
    if not (-reach < u < view.width + reach and -reach < v < view.height_px + reach):
        return None
    canvas = Canvas(extent, min(3.0 * ppm, MAX_CANVAS / extent))
    heading = fig.heading
    lean = 0.0
    if fig.look["kind"] == "person":
        # upright figures are drawn facing the camera so that their height leans away from it
        heading = math.degrees(math.atan2(view.east - east, view.north - north))
        lean = 1.7 * math.tan(math.radians(off_nadir_deg(view, east, north)))
    sun = math.radians(sun_deg + 180.0 - heading)
    draw(canvas, fig.look, t, rng, lean=lean, sun=sun)
    box = place(frame, canvas, jac, (u, v), heading)
    if box is None:
        return None
    x, y, w, hh = box
    x0, y0 = max(x, 0.0), max(y, 0.0)
    x1, y1 = min(x + w, float(view.width)), min(y + hh, float(view.height_px))
    if x1 - x0 < 2 or y1 - y0 < 2:
        return None
    return [round(x0, 2), round(y0, 2), round(x1 - x0, 2), round(y1 - y0, 2)]
