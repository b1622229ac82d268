"""Ready-made scenarios with the survey flight they are meant to be seen from.

Each preset pairs a :class:`Scenario` with a :class:`MissionConfig` (lawnmower legs at a fixed
altitude, nadir 4K camera on a gimbal, starting at altitude). Targets are spread over the strip the
legs see (the area widened by half the camera footprint), with counts chosen for an average number
of targets per frame::

    footprint = (W * gsd) x (H * gsd),   gsd = altitude / f,   f = (W / 2) / tan(hfov / 2)
    targets   = per_frame * strip_area / footprint_area

Splits differ in seed, sea state, altitude and sun. Training draws on three presets:
``maritime_train`` (70 m, sea state 2) and ``maritime_train_high`` (110 m, sea state 4), which
bracket the validation and test conditions, and ``maritime_train_narrow``, rendered small
(960x540 through a 35 degree lens, the view of ``sarmission demo``), where wave and foam detail
falls on far fewer pixels than at 4K. ``maritime_test`` is dense (about 12 targets
per frame, like the paper's test split) at 90 m with a 75 degree lens, where head-only swimmers
fall in the extremely tiny band (<= 64 px^2), head-and-shoulders in the tiny band and swimmers
floating on their back in the small band.

The ``maritime_oblique_*`` presets fly SeaDronesSee's views instead (its validation file's height
and gimbal pitch p10 / p50 / p90 paired, as high flights there look further down): 10 m at 11
degrees below the horizon (horizon and sky in view), 36 m at 36 and 60 m at 71. Their figures
stand up out of the water (``figures = "upright"``) at real sizes, within the distances real
footage shows people at, with the file's classes (boats, jetskis, buoys, life rings) beside
swimmers; ``tools/sim_vs_real.py`` compares their distributions with the real file's.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, replace

from sarmission.mission.config import AreaConfig, CameraConfig, FlightConfig, MissionConfig
from sim.scene import Scenario


@dataclass(frozen=True)
class Preset:
    """A named scenario and the mission (flight and camera) to render it with."""

    name: str
    scenario: Scenario
    mission: MissionConfig


def _mission(
    name: str,
    rect: tuple[float, float, float, float],
    altitude: float,
    hfov: float,
    home: tuple[float, float, float],
    speed: float = 10.0,
    pitch_deg: float = -90.0,
) -> MissionConfig:
    return MissionConfig(
        area=AreaConfig(
            home_lat=home[0],
            home_lon=home[1],
            home_alt_m=home[2],
            ground_alt_m=home[2],
            rectangle_m=rect,
            leg_spacing_m=60.0,
            heading_deg=90.0,
        ),
        flight=FlightConfig(altitude_m=altitude, speed_m_s=speed, takeoff=False),
        camera=CameraConfig(hfov_deg=hfov, mount_pitch_deg=pitch_deg, gimbal=True),
        name=name,
    )


def _strip(
    rect: tuple[float, float, float, float], altitude: float, hfov: float
) -> tuple[tuple[float, float, float, float], float]:
    """Area the legs see (rect widened by half a 3840x2160 footprint) and the footprint area."""
    gsd = altitude / (1920.0 / math.tan(math.radians(hfov) / 2))
    half_e, half_n = 1920 * gsd, 1080 * gsd
    n0, e0, n1, e1 = rect
    strip = (n0 - half_n, e0 - half_e, n1 + half_n, e1 + half_e)
    return strip, (2 * half_e) * (2 * half_n)


def _count(per_frame: float, strip: tuple[float, float, float, float], footprint: float) -> int:
    n0, e0, n1, e1 = strip
    return max(1, round(per_frame * (n1 - n0) * (e1 - e0) / footprint))


def _maritime(
    name: str,
    seed: int,
    altitude: float,
    hfov: float,
    sea_state: int,
    per_frame: float,
    sun: tuple[float, float],
) -> Preset:
    rect = (30.0, -150.0, 90.0, 150.0)  # two legs, at north 30 and 90
    strip, footprint = _strip(rect, altitude, hfov)
    n = _count(per_frame, strip, footprint)
    scenario = Scenario(
        kind="maritime",
        seed=seed,
        area_ne=strip,
        sea_state=sea_state,
        n_swimmers=round(0.65 * n),
        n_life_jacket=n - round(0.65 * n),
        n_boats=max(1, round(0.04 * n)),
        n_birds=max(2, round(0.06 * n)),
        n_debris=round(0.5 * n),
        n_glints=round(0.8 * n),
        head_only_fraction=0.25,
        floating_fraction=0.2,
        sun_azimuth_deg=sun[0],
        sun_elevation_deg=sun[1],
    )
    return Preset(name, scenario, _mission(name, rect, altitude, hfov, (54.178, 7.892, 0.0)))


def oblique_view_m(
    altitude: float, hfov: float, pitch_deg: float, aspect: float = 9 / 16, cap_m: float = 200.0
) -> tuple[float, float, float]:
    """(near, far, area) of the sea an oblique camera sees: the bottom and top edges' ground
    distances ``h / tan(depression -+ vfov/2)`` (``far`` capped at ``cap_m``, and ``cap_m`` when
    the horizon is in view; negative ``near``: behind the drone) and the trapezoid between them,
    each edge as wide as the frame at its slant range."""
    half_h = math.radians(hfov) / 2
    half_v = math.atan(math.tan(half_h) * aspect)
    depression = math.radians(-pitch_deg)
    top, bottom = depression - half_v, depression + half_v
    far = cap_m if top <= math.radians(1.0) else min(cap_m, altitude / math.tan(top))
    near = (
        altitude / math.tan(bottom)
        if bottom < math.pi / 2
        else -altitude * math.tan(bottom - math.pi / 2)
    )

    def width(d: float) -> float:
        return 2 * math.hypot(d, altitude) * math.tan(half_h)

    return near, far, (far - near) * (width(near) + width(far)) / 2


def _maritime_oblique(
    name: str,
    seed: int,
    altitude: float,
    pitch_deg: float,
    hfov: float,
    sea_state: int,
    per_frame: float,
    sun: tuple[float, float],
    reach_m: float,
) -> Preset:
    """A maritime scene seen obliquely, the way real footage of swimmers is taken: the drone
    works slowly (2 m/s) over a small box, two 20 m legs east and west 60 m apart with the
    camera looking ahead, and objects lie within ``reach_m`` of the box all round, about
    ``per_frame`` of them in the sea a frame shows (:func:`oblique_view_m`, out to ``reach_m``).
    Figures stand up out of the water (``figures = "upright"``) and the class mix is
    SeaDronesSee's: about 64 % swimmers, 23 % boats, 6 % buoys, 3 % jetskis and 3 % life rings
    of what a frame shows (boats and jetskis loop across and beyond the area, so more are
    placed than a frame shows); buoys are moored up to ``2 * reach_m`` further out.
    """
    rect = (30.0, -10.0, 90.0, 10.0)
    _, _, area = oblique_view_m(altitude, hfov, pitch_deg, cap_m=reach_m)
    strip = (rect[0] - reach_m, rect[1] - reach_m, rect[2] + reach_m, rect[3] + reach_m)
    n = _count(per_frame, strip, area)
    swimmers = round(0.64 * n)
    moorings = (
        strip[0] - 2 * reach_m,
        strip[1] - 2 * reach_m,
        strip[2] + 2 * reach_m,
        strip[3] + 2 * reach_m,
    )
    spread = (
        (moorings[2] - moorings[0])
        * (moorings[3] - moorings[1])
        / ((strip[2] - strip[0]) * (strip[3] - strip[1]))
    )
    scenario = Scenario(
        kind="maritime",
        seed=seed,
        area_ne=strip,
        sea_state=sea_state,
        n_swimmers=round(0.8 * swimmers),
        n_life_jacket=swimmers - round(0.8 * swimmers),
        n_boats=max(1, round(0.25 * n)),
        n_jetskis=max(1, round(0.06 * n)),
        n_buoys=max(1, round(0.012 * n * spread)),
        buoy_area_ne=moorings,
        n_life_rings=max(1, round(0.03 * n)),
        n_birds=max(2, round(0.06 * n)),
        n_debris=round(0.3 * n),
        n_glints=round(0.5 * n),
        sun_azimuth_deg=sun[0],
        sun_elevation_deg=sun[1],
        figures="upright",
    )
    return Preset(
        name,
        scenario,
        _mission(name, rect, altitude, hfov, (54.178, 7.892, 0.0), speed=2.0, pitch_deg=pitch_deg),
    )


def _urban(
    name: str, seed: int, altitude: float, hfov: float, per_frame: float, sun: tuple[float, float]
) -> Preset:
    rect = (30.0, -90.0, 90.0, 90.0)
    strip, footprint = _strip(rect, altitude, hfov)
    n = _count(per_frame, strip, footprint)
    scenario = Scenario(
        kind="urban",
        seed=seed,
        area_ne=strip,
        n_pedestrians=n,
        n_parked_cars=3 * n,
        n_moving_cars=max(2, n // 2),
        sun_azimuth_deg=sun[0],
        sun_elevation_deg=sun[1],
    )
    return Preset(
        name, scenario, _mission(name, rect, altitude, hfov, (48.137, 11.576, 519.0), speed=8.0)
    )


def maritime_train() -> Preset:
    """Calm to moderate sea, 70 m, about 6 targets per frame."""
    return _maritime("maritime_train", 1001, 70.0, 70.0, 2, 6.0, (200.0, 45.0))


def maritime_train_high() -> Preset:
    """Rough sea (state 4), 110 m, about 10 targets per frame: the training split's far end."""
    return _maritime("maritime_train_high", 1102, 110.0, 75.0, 4, 10.0, (300.0, 40.0))


def maritime_train_narrow() -> Preset:
    """Calm sea, 70 m, a 35 degree lens: the demo's view, meant for 960x540 frames."""
    return _maritime("maritime_train_narrow", 1103, 70.0, 35.0, 2, 6.0, (250.0, 50.0))


def maritime_val() -> Preset:
    """Rougher sea (state 4), 100 m, about 8 targets per frame, low sun."""
    return _maritime("maritime_val", 2002, 100.0, 75.0, 4, 8.0, (150.0, 30.0))


def maritime_test() -> Preset:
    """Dense (about 12 targets per frame), sea state 3, 90 m, 75 degree lens."""
    return _maritime("maritime_test", 3003, 90.0, 75.0, 3, 12.0, (230.0, 50.0))


def maritime_oblique(
    altitude: float, depression_deg: float, seed: int = 7100, reach_m: float = 100.0
) -> Preset:
    """An oblique maritime view at any height and depression (degrees below the horizon), as the
    ``maritime_oblique_*`` presets build theirs: for measuring across view angles."""
    name = f"maritime_oblique_{altitude:g}m_{depression_deg:g}deg"
    return _maritime_oblique(
        name, seed, altitude, -depression_deg, 70.0, 3, 6.0, (200.0, 45.0), reach_m
    )


def maritime_oblique_low() -> Preset:
    """10 m up, looking 11 degrees down (horizon and sky in view): SeaDronesSee's p10 view."""
    return _maritime_oblique(
        "maritime_oblique_low", 7007, 10.0, -11.0, 70.0, 2, 6.0, (200.0, 45.0), 100.0
    )


def maritime_oblique_mid() -> Preset:
    """36 m up, looking 36 degrees down: SeaDronesSee's median height and pitch."""
    return _maritime_oblique(
        "maritime_oblique_mid", 7008, 36.0, -36.0, 70.0, 3, 6.0, (150.0, 35.0), 70.0
    )


def maritime_oblique_high() -> Preset:
    """60 m up, looking 71 degrees down: SeaDronesSee's p90 height and pitch."""
    return _maritime_oblique(
        "maritime_oblique_high", 7009, 60.0, -71.0, 70.0, 3, 6.0, (250.0, 50.0), 60.0
    )


def maritime_objects_train() -> Preset:
    """Training only: 30 m up, looking 40 degrees down, crowded with what is no swimmer (boats,
    jetskis, buoys moored in view, life rings) beside swimmers, so that a head sees enough of
    each to learn it as a class of its own; the other presets show a few per flight."""
    base = _maritime_oblique(
        "maritime_objects_train", 7021, 30.0, -40.0, 70.0, 3, 8.0, (180.0, 40.0), 60.0
    )
    sc = base.scenario
    people = sc.n_swimmers + sc.n_life_jacket
    scenario = replace(
        sc,
        n_boats=max(sc.n_boats, people // 3),
        n_jetskis=max(4, people // 3),
        n_buoys=max(4, people // 3),
        buoy_area_ne=sc.area_ne,
        n_life_rings=max(6, people // 2),
    )
    return Preset(base.name, scenario, base.mission)


def maritime_floats_train() -> Preset:
    """Training only: sea state 3 at 100 m, where people float on their back in about half the
    cases, most of them with arms and legs spread (the survival float); the other presets draw
    people on their back rarely and never spread out."""
    base = _maritime("maritime_floats_train", 1205, 100.0, 75.0, 3, 8.0, (120.0, 35.0))
    scenario = replace(
        base.scenario, head_only_fraction=0.15, floating_fraction=0.45, starfish_fraction=0.7
    )
    return Preset(base.name, scenario, base.mission)


def maritime_buoys_train() -> Preset:
    """Training only: sea state 2 at 80 m, with a round mooring buoy for every person in the
    water; the other flat presets draw no buoys."""
    base = _maritime("maritime_buoys_train", 1306, 80.0, 75.0, 2, 6.0, (160.0, 40.0))
    sc = base.scenario
    scenario = replace(sc, n_mooring_buoys=sc.n_swimmers + sc.n_life_jacket)
    return Preset(base.name, scenario, base.mission)


def maritime_buoys_high_train() -> Preset:
    """Training only: :func:`maritime_buoys_train`'s calm sea at 150 m, where buoys and people
    in life jackets are blobs of 10-20 px, too small to show the shapes that tell them apart
    from 80 m (docs/box_colours.md)."""
    base = _maritime("maritime_buoys_high_train", 1307, 150.0, 75.0, 2, 6.0, (140.0, 45.0))
    sc = base.scenario
    scenario = replace(sc, n_mooring_buoys=sc.n_swimmers + sc.n_life_jacket)
    return Preset(base.name, scenario, base.mission)


def urban_train() -> Preset:
    """City blocks at 60 m, about 6 pedestrians per frame."""
    return _urban("urban_train", 4004, 60.0, 70.0, 6.0, (160.0, 40.0))


def urban_val() -> Preset:
    """City blocks at 80 m, about 6 pedestrians per frame."""
    return _urban("urban_val", 5005, 80.0, 75.0, 6.0, (210.0, 55.0))


def urban_test() -> Preset:
    """City blocks at 100 m, about 10 pedestrians per frame (extremely tiny targets)."""
    return _urban("urban_test", 6006, 100.0, 75.0, 10.0, (120.0, 35.0))


def _wild(
    name: str,
    seed: int,
    biome: str,
    altitude: float,
    hfov: float,
    per_frame: float,
    sun: tuple[float, float],
    home: tuple[float, float, float],
) -> Preset:
    rect = (30.0, -90.0, 90.0, 90.0)
    strip, footprint = _strip(rect, altitude, hfov)
    n = _count(per_frame, strip, footprint)
    scenario = Scenario(
        kind="wild",
        seed=seed,
        area_ne=strip,
        biome=biome,
        n_pedestrians=n,
        n_animals=max(1, n // 2),
        sun_azimuth_deg=sun[0],
        sun_elevation_deg=sun[1],
    )
    return Preset(name, scenario, _mission(name, rect, altitude, hfov, home, speed=6.0))


def wild_meadow_train() -> Preset:
    """Meadow with bushes, a few trees and a trail at 60 m, about 5 people per frame."""
    return _wild(
        "wild_meadow_train", 4101, "meadow", 60.0, 70.0, 5.0, (150.0, 45.0), (47.42, 10.98, 1400.0)
    )


def wild_forest_train() -> Preset:
    """Forest canopy with clearings, logs and a trail at 70 m, about 5 people per frame."""
    return _wild(
        "wild_forest_train", 4102, "forest", 70.0, 70.0, 5.0, (200.0, 50.0), (61.05, 24.50, 120.0)
    )


def wild_rock_train() -> Preset:
    """Boulder field and scree at 60 m, about 5 people per frame."""
    return _wild(
        "wild_rock_train", 4103, "rock", 60.0, 75.0, 5.0, (110.0, 35.0), (46.55, 8.03, 2300.0)
    )


def wild_snow_train() -> Preset:
    """Snow with rocks, conifers and tracks at 70 m, about 5 people per frame."""
    return _wild(
        "wild_snow_train", 4104, "snow", 70.0, 70.0, 5.0, (170.0, 25.0), (46.02, 7.75, 2600.0)
    )


def wild_sand_train() -> Preset:
    """Dunes with ripples, shrubs and driftwood at 60 m, about 5 people per frame."""
    return _wild(
        "wild_sand_train", 4105, "sand", 60.0, 70.0, 5.0, (230.0, 60.0), (54.45, 8.30, 5.0)
    )


PRESETS: dict[str, Callable[[], Preset]] = {
    f.__name__: f
    for f in (
        maritime_train,
        maritime_train_high,
        maritime_train_narrow,
        maritime_val,
        maritime_test,
        maritime_oblique_low,
        maritime_oblique_mid,
        maritime_oblique_high,
        maritime_objects_train,
        maritime_floats_train,
        maritime_buoys_train,
        maritime_buoys_high_train,
        urban_train,
        urban_val,
        urban_test,
        wild_meadow_train,
        wild_forest_train,
        wild_rock_train,
        wild_snow_train,
        wild_sand_train,
    )
}


def preset(name: str) -> Preset:
    """The preset called ``name`` (one of :data:`PRESETS`)."""
    try:
        return PRESETS[name]()
    except KeyError:
        raise ValueError(f"unknown scenario preset {name!r}; known: {', '.join(PRESETS)}") from None
