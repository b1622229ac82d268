"""The held-out worlds: ranges each clip draws its sea or land, light, flight and camera from.

Frames are 1920x1080 windows with the ground sampling of a 4K camera: the lens is the centre
of a 3840-px-wide lens of 70-80 degrees, so people cover as many pixels as in 4K footage while a
frame costs a quarter to render and to evaluate. Seeds of the held-out clips are never used for
training or by ``sim/``.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

import numpy as np

from heldout.camera import Lens, ground_points
from heldout.land import LandLook
from heldout.optics import Sensor
from heldout.path import draw_path
from heldout.scene import ClipSpec
from heldout.sea import WATER_BODIES, Light, SeaLook
from heldout.waves import SEA_STATES, draw_trains
from heldout.world import Population, populate

SEA_HOME = (43.2965, 5.3698)
LAND_HOME = (61.4978, 23.7610)


@dataclass(frozen=True)
class WorldPreset:
    """A held-out world: what its clips are drawn from."""

    name: str
    kind: str
    seed: int
    altitude_m: tuple[float, float]
    speed_m_s: tuple[float, float]
    tilt_deg: tuple[float, float]
    sea_states: tuple[int, ...]
    sun_elevation_deg: tuple[float, float]
    population: Population
    description: str


def equivalent_hfov(width: int, hfov_4k_deg: float) -> float:
    """Field of view of a ``width``-px window of a 3840-px frame taken through ``hfov_4k_deg``."""
    half = math.tan(math.radians(hfov_4k_deg) / 2) * width / 3840.0
    return math.degrees(2 * math.atan(half))


def _light(rng: np.random.Generator, elevation: tuple[float, float], kind: str) -> Light:
    haze = float(rng.uniform(0.0, 1.0))
    grey = 0.30 + 0.25 * haze
    return Light(
        sun_azimuth_deg=float(rng.uniform(0, 360)),
        sun_elevation_deg=float(rng.uniform(*elevation)),
        sun_radiance=float(rng.uniform(2.0, 3.5))
        if kind == "sea"
        else float(rng.uniform(1.2, 2.0)),
        zenith_bgr=(float(rng.uniform(0.30, 0.45)), 0.20, 0.08),
        horizon_bgr=(0.55, 0.52, 0.48),
        haze_bgr=(grey * 1.08, grey, grey * 0.94),
        visibility_m=float(np.exp(rng.uniform(math.log(1500), math.log(20000)))),
    )


def _sensor(rng: np.random.Generator) -> Sensor:
    return Sensor(
        blur_sigma_px=float(rng.uniform(0.5, 1.0)),
        exposure_s=float(rng.choice([1 / 1000, 1 / 500, 1 / 250, 1 / 120])),
        shot_noise=float(rng.uniform(2.0, 12.0)),
        read_noise=float(rng.uniform(0.8, 2.5)),
        vignette=float(rng.uniform(0.05, 0.3)),
    )


def _seen_area(
    lens: Lens, path, duration_s: float, margin_m: float
) -> tuple[float, float, float, float]:
    corners_u = np.array([0.0, lens.width, 0.0, lens.width])
    corners_v = np.array([0.0, 0.0, lens.height, lens.height])
    pts = []
    for t in np.linspace(0.0, duration_s, 5):
        ground, _ = ground_points(lens, path.view(float(t)), corners_u, corners_v)
        pts.append(ground)
    pts = np.concatenate(pts)
    return (
        float(np.nanmin(pts[:, 0])) - margin_m,
        float(np.nanmin(pts[:, 1])) - margin_m,
        float(np.nanmax(pts[:, 0])) + margin_m,
        float(np.nanmax(pts[:, 1])) + margin_m,
    )


def draw_clip(
    preset: WorldPreset, index: int, width: int, height: int, duration_s: float
) -> ClipSpec:
    """Clip ``index`` of ``preset``: every choice from ``preset.seed`` and ``index``."""
    seed = preset.seed * 1000 + index
    rng = np.random.default_rng(seed)
    lens = Lens(width, height, equivalent_hfov(width, float(rng.uniform(70, 80))))
    light = _light(rng, preset.sun_elevation_deg, preset.kind)
    path = draw_path(rng, preset.altitude_m, preset.speed_m_s, preset.tilt_deg)
    sensor = _sensor(rng)
    area = _seen_area(lens, path, duration_s, margin_m=25.0)
    gsd = path.altitude_m / lens.focal_px
    footprint = width * height * gsd * gsd
    if preset.kind == "sea":
        sea_state = int(rng.choice(preset.sea_states))
        wind_from = float(rng.uniform(0, 360))
        water = WATER_BODIES[str(rng.choice(sorted(WATER_BODIES)))]
        hs = SEA_STATES[sea_state][0]
        look = SeaLook(
            water_bgr=water,
            facet_variance=SEA_STATES[sea_state][2],
            whitecap_height_m=0.55 * hs + 0.15,
            foam_cover=0.08 * sea_state,
            wind_to_deg=wind_from + 180.0,
            seed=seed,
        )
        trains = draw_trains(rng, sea_state, wind_from)
        c = math.radians(wind_from + 180.0)
        drift = float(rng.uniform(0.05, 0.4))
        things = populate(
            rng,
            preset.population,
            area,
            footprint,
            water,
            (drift * math.sin(c), drift * math.cos(c)),
        )
        return ClipSpec(
            seed,
            "sea",
            lens,
            light,
            path,
            sensor,
            tuple(things),
            SEA_HOME,
            sea_state=sea_state,
            trains=trains,
            sea=look,
        )
    road_heading = float(rng.uniform(0, 180))
    h = math.radians(road_heading)
    start_across = path.start[0] * math.cos(h) - path.start[1] * math.sin(h)
    land = LandLook(
        seed=seed,
        forest_share=float(rng.uniform(0.15, 0.5)),
        road_heading_deg=road_heading,
        road_offset_m=start_across + float(rng.uniform(-15, 15)),
        road_width_m=float(rng.uniform(3, 6)),
        lush_bgr=(0.04, float(rng.uniform(0.12, 0.18)), 0.07),
        dry_bgr=(0.09, 0.20, float(rng.uniform(0.20, 0.28))),
    )
    things = populate(rng, preset.population, area, footprint, (0.0, 0.0, 0.0))
    return ClipSpec(seed, "land", lens, light, path, sensor, tuple(things), LAND_HOME, land=land)


def heldout_maritime() -> WorldPreset:
    """Open sea, states 2-4, 75-120 m, nadir to 20 degrees oblique, about 6 people per frame."""
    return WorldPreset(
        "heldout_maritime",
        "sea",
        7731,
        (75.0, 120.0),
        (0.0, 8.0),
        (0.0, 20.0),
        (2, 3, 4),
        (20.0, 65.0),
        Population(
            {
                "swimmer": 4.0,
                "swimmer_with_life_jacket": 2.5,
                "buoy": 0.8,
                "debris": 2.0,
                "bird": 0.8,
                "boat": 0.15,
            }
        ),
        heldout_maritime.__doc__ or "",
    )


def heldout_land() -> WorldPreset:
    """Meadow, forest and a dirt road, 75-120 m, nadir to 20 degrees, about 5 people per frame."""
    return WorldPreset(
        "heldout_land",
        "land",
        7742,
        (75.0, 120.0),
        (0.0, 7.0),
        (0.0, 20.0),
        (),
        (25.0, 60.0),
        Population({"person": 5.0, "rock": 3.0, "log": 1.5, "animal": 0.5, "bird": 0.3}),
        heldout_land.__doc__ or "",
    )


def _without_people(preset: WorldPreset, name: str, seed: int) -> WorldPreset:
    """``preset`` with its people left out (its distractors kept), under its own seed."""
    kept = {k: v for k, v in preset.population.per_frame.items() if k not in PEOPLE}
    return replace(
        preset,
        name=name,
        seed=seed,
        population=Population(kept),
        description=f"{preset.description.rstrip('.')}; background only: no people.",
    )


def heldout_maritime_empty() -> WorldPreset:
    """The held-out sea without people: buoys, debris, birds and boats only."""
    return _without_people(heldout_maritime(), "heldout_maritime_empty", 7733)


def heldout_maritime_clutter() -> WorldPreset:
    """The held-out sea's distractors, many to a frame and no people: buoys six times, debris
    four times, birds three times and boats twice as dense as in ``heldout_maritime``, so that
    validation counts enough objects to tell heads apart by what they take for a person."""
    empty = _without_people(heldout_maritime(), "heldout_maritime_clutter", 7735)
    dense = {"buoy": 6.0, "debris": 4.0, "bird": 3.0, "boat": 2.0}
    return replace(
        empty,
        population=Population({k: v * dense[k] for k, v in empty.population.per_frame.items()}),
        description=heldout_maritime_clutter.__doc__ or "",
    )


def heldout_land_empty() -> WorldPreset:
    """The held-out land without people: rocks, logs, animals and birds only."""
    return _without_people(heldout_land(), "heldout_land_empty", 7744)


#: The kinds that are people (left out of the background-only worlds).
PEOPLE = ("person", "swimmer", "swimmer_with_life_jacket")

WORLDS: dict[str, Callable[[], WorldPreset]] = {
    "heldout_maritime": heldout_maritime,
    "heldout_land": heldout_land,
    "heldout_maritime_empty": heldout_maritime_empty,
    "heldout_land_empty": heldout_land_empty,
    "heldout_maritime_clutter": heldout_maritime_clutter,
}


def world(name: str) -> WorldPreset:
    """The held-out world called ``name``."""
    try:
        return WORLDS[name]()
    except KeyError:
        raise ValueError(f"unknown held-out world {name!r}; known: {', '.join(WORLDS)}") from None
