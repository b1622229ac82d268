"""The simulated world: a seeded scenario and the objects in it, in local NED metres.

The sea (or ground) is the plane ``down = 0``. Every object is a flat figure made of a few
:class:`Part` shapes (ellipses and rounded boxes) lying in the horizontal plane
``down = -height_m`` (swimmers, boats, debris and cars at 0, birds some metres up). Part
coordinates are object-local metres: ``x`` forward along the object's heading, ``y`` to its right.
Local ``(x, y)`` maps to the world as::

    north = n + x cos(psi) - y sin(psi)
    east  = e + x sin(psi) + y cos(psi)

with ``psi`` the heading (clockwise from north). :meth:`SceneObject.state_at` gives the exact
position, heading, parts (arms swung, wings flapped, glints flickered) and visibility at time ``t``;
everything is a closed-form function of ``t``, so any frame can be rendered in any order.

Motion models:

- swimmers and debris drift with a constant current (0.1-0.5 m/s) plus a slow circular wander;
  swimmers' arms swing with a stroke period of 1.5-3 s and show only while out of the water;
  their visibility dips as waves wash over them (deeper dips at higher sea states);
- boats, cars and birds move at constant velocity and loop over a path that is longer than the
  area (they leave on one side and come back on the other);
- pedestrians walk back and forth along a segment;
- sun glints sit still, each flashing on for part of its period.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

BGR = tuple[float, float, float]

#: Annotation categories (COCO ids) and whether each is a search target.
CATEGORIES: dict[str, int] = {
    "swimmer": 1,
    "swimmer_with_life_jacket": 2,
    "boat": 3,
    "bird": 4,
    "debris": 5,
    "sun_glint": 6,
    "person": 7,
    "car": 8,
    "jetski": 9,
    "buoy": 10,
    "life_saving_appliances": 11,
    "animal": 12,
}
#: Categories that are people to find. The maritime detector's classes are the first two;
#: ``person`` is a person on land in urban scenes.
TARGET_CATEGORIES: tuple[str, ...] = ("swimmer", "swimmer_with_life_jacket", "person")

SKIN: tuple[BGR, ...] = ((128, 160, 214), (105, 140, 196), (80, 110, 160), (55, 75, 110))
HAIR: tuple[BGR, ...] = ((22, 22, 26), (30, 45, 70), (60, 100, 150), (95, 165, 205))
SWIM_CAP: tuple[BGR, ...] = ((235, 235, 235), (40, 40, 205), (30, 200, 235), (200, 120, 30))
WETSUIT: tuple[BGR, ...] = ((28, 28, 30), (60, 40, 28), (45, 45, 50), (35, 30, 60))
LIFE_JACKET: tuple[BGR, ...] = ((10, 105, 250), (20, 85, 235), (25, 60, 220), (10, 190, 245))
HULL: tuple[BGR, ...] = (
    (235, 235, 232),
    (200, 200, 196),
    (40, 50, 190),
    (150, 80, 30),
    (20, 110, 245),
    (60, 60, 60),
)
DEBRIS: tuple[BGR, ...] = (
    (45, 75, 105),
    (215, 215, 210),
    (160, 95, 35),
    (60, 120, 60),
    (30, 30, 35),
)
CAR: tuple[BGR, ...] = (
    (235, 235, 235),
    (25, 25, 28),
    (170, 170, 170),
    (40, 40, 170),
    (140, 80, 30),
    (60, 90, 60),
    (120, 120, 125),
)
#: Disturbed water around something afloat.
RIPPLE: BGR = (225.0, 225.0, 215.0)
CLOTHES: tuple[BGR, ...] = (
    (40, 40, 40),
    (150, 60, 30),
    (40, 40, 170),
    (200, 200, 200),
    (60, 120, 60),
    (30, 160, 220),
    (110, 90, 80),
)


@dataclass(frozen=True)
class Part:
    """One shape of an object, in object-local metres.

    ``shape`` is ``"ellipse"`` (half-axes ``a`` along ``angle``, ``b`` across) or ``"box"`` (a
    rounded rectangle of half-sizes ``a``, ``b``). ``opacity`` in [0, 1] blends the part over what
    lies below (a submerged shoulder is half transparent); ``shade`` darkens it towards its rim.
    ``in_box`` parts make up the annotated extent (a wake or a ripple ring does not).

    ``role`` animates the part: ``"arm"`` swings by ``swing`` radians about the pivot ``(x, y)``
    and shows only while out of the water, ``"limb"`` swings ``swing`` metres forward and back
    (a walker's arm), ``"wing"`` flaps (its length pulses) about the pivot,
    ``"glint"`` flashes. For arms and wings ``(x, y)`` is the pivot and the ellipse reaches from
    it along ``angle``; ``phase`` offsets the cycle.
    """

    shape: str
    x: float
    y: float
    a: float
    b: float
    angle: float
    bgr: BGR
    opacity: float = 1.0
    shade: float = 0.25
    in_box: bool = True
    role: str = ""
    swing: float = 0.0
    phase: float = 0.0

    def placed(self) -> Part:
        """The part with arm/wing pivots resolved to an ellipse centre (role cleared)."""
        if self.role not in ("arm", "wing"):
            return self
        c, s = math.cos(self.angle), math.sin(self.angle)
        return replace(self, x=self.x + self.a * c, y=self.y + self.a * s, role="")


@dataclass(frozen=True)
class Upright:
    """A part standing up from the object's plane (a head above the water, a hull's side, a
    person on deck), seen from the side.

    Its footprint is centred at object-local ``(x, y)`` metres with half-extents ``half_length``
    along ``x`` and ``half_width`` along ``y``; it rises from ``bottom`` to ``top`` metres above
    the plane. It is drawn as ``shape`` (``"ellipse"`` or ``"box"``) on a billboard facing the
    camera (:mod:`sim.billboard`), as wide as its footprint looks from there. ``tilt`` leans it
    about its foot (radians from vertical, towards the viewer's right); ``swing`` rocks the tilt
    by that much over the object's ``period_s`` (a waving arm).
    """

    shape: str
    x: float
    y: float
    half_length: float
    half_width: float
    bottom: float
    top: float
    bgr: BGR
    opacity: float = 1.0
    shade: float = 0.25
    in_box: bool = True
    tilt: float = 0.0
    swing: float = 0.0
    phase: float = 0.0


@dataclass
class ObjectState:
    """An object at one instant: world position (NED, ``down = -height``), heading, parts
    (flat, in its plane) and upright parts."""

    track_id: int
    category: str
    position_ned: np.ndarray
    heading: float
    parts: list[Part]
    visibility: float
    upright: list[Upright] = field(default_factory=list)

    def local_to_ne(self) -> np.ndarray:
        """3x3 matrix taking homogeneous local ``(x, y, 1)`` to ``(north, east, 1)``."""
        c, s = math.cos(self.heading), math.sin(self.heading)
        n, e = float(self.position_ned[0]), float(self.position_ned[1])
        return np.array([[c, -s, n], [s, c, e], [0.0, 0.0, 1.0]])


@dataclass
class SceneObject:
    """A world object and its motion (see the module docstring for the models).

    ``origin_ne`` is the position at ``t = 0`` (for looping movers, the start of the loop),
    ``velocity_ne`` m/s. ``loop_m`` > 0 wraps constant-velocity motion over that path length;
    ``patrol_m`` > 0 walks back and forth over that length. ``wander_m`` / ``wander_period_s``
    add a slow circle to drifting objects. ``static`` objects are painted into the ground texture
    (parked cars) rather than drawn per frame.
    """

    track_id: int
    category: str
    origin_ne: tuple[float, float]
    heading: float
    parts: list[Part]
    velocity_ne: tuple[float, float] = (0.0, 0.0)
    height_m: float = 0.0
    loop_m: float = 0.0
    patrol_m: float = 0.0
    wander_m: float = 0.0
    wander_period_s: float = 60.0
    turn_rate: float = 0.0
    period_s: float = 2.0
    duty: float = 1.0
    bob_depth: float = 0.0
    bob_period_s: float = 4.0
    phase: float = 0.0
    static: bool = False
    upright: list[Upright] = field(default_factory=list)

    @property
    def is_target(self) -> bool:
        """True for the people the search is for."""
        return self.category in TARGET_CATEGORIES

    def _position(self, t: float) -> tuple[float, float, float]:
        """(north, east, heading) at ``t``."""
        n0, e0 = self.origin_ne
        vn, ve = self.velocity_ne
        speed = math.hypot(vn, ve)
        heading = self.heading + self.turn_rate * t
        if self.loop_m > 0 and speed > 0:
            s = (self.phase * self.loop_m + speed * t) % self.loop_m
            return n0 + vn / speed * s, e0 + ve / speed * s, heading
        if self.patrol_m > 0 and speed > 0:
            s = (self.phase * 2 * self.patrol_m + speed * t) % (2 * self.patrol_m)
            back = s > self.patrol_m
            s = 2 * self.patrol_m - s if back else s
            return n0 + vn / speed * s, e0 + ve / speed * s, heading + (math.pi if back else 0.0)
        n, e = n0 + vn * t, e0 + ve * t
        if self.wander_m > 0:
            w = 2 * math.pi * (t / self.wander_period_s + self.phase)
            n += self.wander_m * (math.cos(w) - math.cos(2 * math.pi * self.phase))
            e += self.wander_m * (math.sin(w) - math.sin(2 * math.pi * self.phase))
        return n, e, heading

    def position_at(self, t: float) -> np.ndarray:
        """Centre (north, east, down) at ``t`` without animating the parts."""
        n, e, _ = self._position(t)
        return np.array([n, e, -self.height_m])

    @functools.cached_property
    def radius_m(self) -> float:
        """Radius of a circle about the centre that holds every part in every pose."""
        flat = (
            math.hypot(p.x, p.y)
            + (2.0 if p.role in ("arm", "wing") else 1.0) * max(p.a, p.b)
            + abs(p.swing)
            for p in self.parts
        )
        upright = (
            math.hypot(u.x, u.y) + max(u.half_length, u.half_width) + u.top for u in self.upright
        )
        return max(*flat, *upright, 0.0)

    def _animate(self, part: Part, t: float) -> Part:
        cycle = 2 * math.pi * (t / self.period_s + self.phase) + part.phase
        if part.role == "arm":
            up = math.sin(cycle)
            opacity = part.opacity * min(1.0, max(0.0, 1.6 * up - 0.2))
            angle = part.angle + part.swing * math.cos(cycle)
            return replace(part, angle=angle, opacity=opacity).placed()
        if part.role == "limb":
            return replace(part, x=part.x + part.swing * math.sin(cycle), role="")
        if part.role == "wing":
            a = part.a * (0.55 + 0.45 * abs(math.cos(cycle)))
            return replace(part, a=a).placed()
        if part.role == "glint":
            frac = (t / self.period_s + self.phase) % 1.0
            on = frac < self.duty
            level = math.sin(math.pi * frac / self.duty) if on else 0.0
            return replace(part, opacity=part.opacity * level, role="")
        return part

    def state_at(self, t: float) -> ObjectState:
        """The exact state at time ``t`` (seconds)."""
        n, e, heading = self._position(t)
        parts = [self._animate(p, t) for p in self.parts]
        visibility = 1.0
        if self.bob_depth > 0:
            wave = 0.5 + 0.5 * math.sin(2 * math.pi * (t / self.bob_period_s + self.phase))
            visibility = 1.0 - self.bob_depth * wave**3
        upright = [
            u
            if not u.swing
            else replace(
                u,
                tilt=u.tilt
                + u.swing * math.sin(2 * math.pi * (t / self.period_s + self.phase) + u.phase),
                swing=0.0,
            )
            for u in self.upright
        ]
        return ObjectState(
            self.track_id,
            self.category,
            np.array([n, e, -self.height_m]),
            heading,
            parts,
            visibility,
            upright,
        )


@dataclass(frozen=True)
class Scenario:
    """A seeded description of one world (everything else follows from it deterministically).

    ``area_ne`` = ``(north_min, east_min, north_max, east_max)`` metres from home is where
    objects are placed. ``sea_state`` (Douglas scale 0-6) sets wave contrast, foam and how often
    waves wash over swimmers. Swimmer sizes: head-and-shoulders across ``swimmer_width_m``;
    ``head_only_fraction`` show only a head (0.18-0.26 m), ``floating_fraction`` float on their
    back (body 1.3-1.8 m long). Life-jacket wearers float on their back in half the cases.
    ``starfish_fraction`` of those floating on their back spread arms and legs wide (the
    survival float taught to people who fall into the water), drawn by a generator of their
    own, so that the rest of the world stays as it is without them.
    ``n_mooring_buoys`` round mooring buoys (0.4-1.2 m, in the colours of life jackets and
    white) swing on their moorings over ``area_ne``; they too come from a generator of their
    own and follow every other object, so a world without them is drawn as before.
    Urban counts apply to ``kind == "urban"``, maritime ones to ``"maritime"``; ``"wild"``
    (:mod:`sim.wild`) is land away from streets of the given ``biome``, with ``n_pedestrians``
    people and ``n_animals`` animals (flat figures only).

    ``figures = "flat"`` lays every object flat on its plane (the look from straight down);
    ``"upright"`` builds the world of :mod:`sim.upright_world` instead: heads and shoulders
    out of the water, people standing on deck and on land, hulls and buoys with height, at the
    sizes of real footage, plus ``n_jetskis``, ``n_buoys`` and ``n_life_rings`` (used only
    there); buoys are moored over ``buoy_area_ne`` (default ``area_ne``), as they mark out
    waters well beyond where people swim.
    """

    kind: str = "maritime"
    seed: int = 0
    area_ne: tuple[float, float, float, float] = (0.0, -150.0, 240.0, 150.0)
    sea_state: int = 2
    n_swimmers: int = 12
    n_life_jacket: int = 6
    n_boats: int = 2
    n_birds: int = 4
    n_debris: int = 10
    n_glints: int = 20
    n_parked_cars: int = 60
    n_moving_cars: int = 12
    n_pedestrians: int = 25
    swimmer_width_m: tuple[float, float] = (0.4, 0.6)
    head_only_fraction: float = 0.2
    floating_fraction: float = 0.2
    starfish_fraction: float = 0.0
    n_mooring_buoys: int = 0
    drift_m_s: tuple[float, float] = (0.1, 0.5)
    wind_from_deg: float = 250.0
    sun_azimuth_deg: float = 200.0
    sun_elevation_deg: float = 45.0
    figures: str = "flat"
    n_jetskis: int = 0
    n_buoys: int = 0
    n_life_rings: int = 0
    buoy_area_ne: tuple[float, float, float, float] | None = None
    biome: str = "meadow"
    n_animals: int = 0

    def __post_init__(self) -> None:
        if self.kind not in ("maritime", "urban", "wild"):
            raise ValueError(f"kind must be 'maritime', 'urban' or 'wild', got {self.kind!r}")
        if self.kind == "wild" and self.figures != "flat":
            raise ValueError("wild scenes have flat figures only")
        if self.figures not in ("flat", "upright"):
            raise ValueError(f"figures must be 'flat' or 'upright', got {self.figures!r}")
        if self.n_mooring_buoys < 0:
            raise ValueError(f"n_mooring_buoys must be >= 0, got {self.n_mooring_buoys}")
        if not 0 <= self.starfish_fraction <= 1:
            raise ValueError(f"starfish_fraction must be in [0, 1], got {self.starfish_fraction}")
        if not 0 <= self.sea_state <= 6:
            raise ValueError(f"sea_state must be 0..6, got {self.sea_state}")
        n0, e0, n1, e1 = self.area_ne
        if n1 <= n0 or e1 <= e0:
            raise ValueError(f"area_ne must be (n_min, e_min, n_max, e_max), got {self.area_ne}")
        if not 0 < self.sun_elevation_deg <= 90:
            raise ValueError("sun_elevation_deg must be in (0, 90]")

    @property
    def sun_direction_ned(self) -> np.ndarray:
        """Unit vector from the scene towards the sun (NED)."""
        az, el = math.radians(self.sun_azimuth_deg), math.radians(self.sun_elevation_deg)
        return np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), -math.sin(el)])


@dataclass
class Building:
    """A flat-roofed building: footprint ``(n0, e0, n1, e1)`` metres, roof colour, height."""

    rect: tuple[float, float, float, float]
    roof_bgr: BGR
    height_m: float


@dataclass
class UrbanLayout:
    """Street grid and blocks: roads every ``block_m`` along north and east from ``origin_ne``.

    Each block holds buildings, a park with trees (``trees``: north, east, radius) or a car park.
    """

    origin_ne: tuple[float, float]
    block_m: float
    road_m: float
    buildings: list[Building] = field(default_factory=list)
    parks: list[tuple[float, float, float, float]] = field(default_factory=list)
    lots: list[tuple[float, float, float, float]] = field(default_factory=list)
    trees: list[tuple[float, float, float]] = field(default_factory=list)

    def road_lines(
        self, area_ne: tuple[float, float, float, float]
    ) -> tuple[list[float], list[float]]:
        """Centre lines inside ``area_ne``: (norths of east-west roads, easts of north-south)."""
        n0, e0, n1, e1 = area_ne
        on, oe = self.origin_ne
        north = [
            on + k * self.block_m
            for k in range(
                math.ceil((n0 - on) / self.block_m), math.floor((n1 - on) / self.block_m) + 1
            )
        ]
        east = [
            oe + k * self.block_m
            for k in range(
                math.ceil((e0 - oe) / self.block_m), math.floor((e1 - oe) / self.block_m) + 1
            )
        ]
        return north, east


@dataclass
class World:
    """A built scenario: its objects and, for urban scenes, the street layout."""

    scenario: Scenario
    objects: list[SceneObject]
    layout: UrbanLayout | None = None


def pick_colour(rng: np.random.Generator, options: tuple[BGR, ...]) -> BGR:
    base = options[int(rng.integers(len(options)))]
    jitter = rng.normal(0.0, 8.0, 3)
    return tuple(float(np.clip(c + j, 0, 255)) for c, j in zip(base, jitter, strict=True))


def uniform_in(
    rng: np.random.Generator, area: tuple[float, float, float, float]
) -> tuple[float, float]:
    n0, e0, n1, e1 = area
    return float(rng.uniform(n0, n1)), float(rng.uniform(e0, e1))


# ----------------------------------------------------------------------------- figures


def swimmer_parts(
    rng: np.random.Generator, width: float, pose: str, life_jacket: bool
) -> list[Part]:
    """Parts of a swimmer. ``pose``: ``"head"`` (only the head shows), ``"tread"`` (head and
    shoulders, arms sweeping), ``"float"`` (on the back, body ``width`` long) or
    ``"starfish"`` (on the back with arms and legs spread, :func:`starfish_parts`)."""
    if pose == "starfish":
        return starfish_parts(rng, width, life_jacket)
    skin = pick_colour(rng, SKIN)
    cover = pick_colour(rng, SWIM_CAP) if rng.random() < 0.3 else pick_colour(rng, HAIR)
    suit = pick_colour(rng, WETSUIT) if rng.random() < 0.6 else skin
    jacket = pick_colour(rng, LIFE_JACKET)
    parts: list[Part] = []
    if pose == "head":
        r = width / 2
        parts.append(Part("ellipse", 0.0, 0.0, 1.7 * r, 1.6 * r, 0.0, RIPPLE, 0.18, 0.0, False))
        parts.append(Part("ellipse", 0.0, 0.0, r, 0.92 * r, 0.0, cover, 0.95, 0.35))
        parts.append(Part("ellipse", 0.35 * r, 0.0, 0.55 * r, 0.6 * r, 0.0, skin, 0.8, 0.2))
        return parts
    if pose == "tread":
        w = width / 2
        head_r = min(0.12, 0.42 * w)
        parts.append(Part("ellipse", 0.0, 0.0, 1.1 * w, 1.35 * w, 0.0, RIPPLE, 0.15, 0.0, False))
        for side in (-1.0, 1.0):
            parts.append(
                Part(
                    "ellipse",
                    0.0,
                    side * 0.8 * w,
                    0.26,
                    0.05,
                    side * math.pi / 2,
                    suit,
                    0.75,
                    0.15,
                    True,
                    "arm",
                    0.6,
                    0.0 if side > 0 else math.pi,
                )
            )
        body = jacket if life_jacket else suit
        parts.append(
            Part(
                "ellipse", -0.05 * w, 0.0, 0.45 * w, w, 0.0, body, 0.95 if life_jacket else 0.7, 0.3
            )
        )
        parts.append(Part("ellipse", 0.02, 0.0, head_r, 0.9 * head_r, 0.0, cover, 0.97, 0.35))
        parts.append(
            Part(
                "ellipse",
                0.02 + 0.45 * head_r,
                0.0,
                0.5 * head_r,
                0.6 * head_r,
                0.0,
                skin,
                0.85,
                0.2,
            )
        )
        return parts
    length = width
    half = length / 2
    torso = pick_colour(rng, CLOTHES) if not life_jacket else jacket
    parts.append(Part("ellipse", 0.0, 0.0, 1.05 * half, 0.32, 0.0, RIPPLE, 0.12, 0.0, False))
    parts.append(Part("ellipse", -0.55 * half, 0.0, 0.45 * half, 0.16, 0.0, suit, 0.35, 0.2))
    for side in (-1.0, 1.0):
        parts.append(
            Part(
                "ellipse",
                0.35 * half,
                side * 0.16,
                0.28,
                0.045,
                side * 1.9,
                skin,
                0.6,
                0.1,
                True,
                "arm",
                0.35,
                0.0 if side > 0 else math.pi,
            )
        )
    parts.append(
        Part(
            "ellipse",
            0.2 * half,
            0.0,
            0.38 * half,
            0.2 if not life_jacket else 0.25,
            0.0,
            torso,
            0.9 if life_jacket else 0.6,
            0.3,
        )
    )
    parts.append(
        Part("ellipse", 0.2 * half + 0.38 * half + 0.08, 0.0, 0.11, 0.095, 0.0, cover, 0.9, 0.3)
    )
    parts.append(
        Part("ellipse", 0.2 * half + 0.38 * half + 0.12, 0.0, 0.06, 0.06, 0.0, skin, 0.8, 0.2)
    )
    return parts


def starfish_parts(rng: np.random.Generator, length: float, life_jacket: bool) -> list[Part]:
    """A person floating on the back, arms and legs spread wide, ``length`` metres from head to
    feet: a small torso and head at the surface, thin limbs just under it (fainter the deeper
    the legs hang), the whole figure boxed. The body axis points along local ``x``."""
    k = length / 1.7
    skin = pick_colour(rng, SKIN)
    cover = pick_colour(rng, SWIM_CAP) if rng.random() < 0.3 else pick_colour(rng, HAIR)
    suit = pick_colour(rng, WETSUIT) if rng.random() < 0.6 else pick_colour(rng, CLOTHES)
    torso = pick_colour(rng, LIFE_JACKET) if life_jacket else suit
    arms = skin if rng.random() < 0.5 else suit
    parts = [Part("ellipse", 0.0, 0.0, 0.95 * k, 0.8 * k, 0.0, RIPPLE, 0.1, 0.0, False)]
    legs_opacity = float(rng.uniform(0.25, 0.55))
    for side in (-1.0, 1.0):
        spread = math.radians(rng.uniform(150.0, 170.0))
        leg = 0.42 * k
        parts.append(
            Part(
                "ellipse",
                -0.2 * k + leg * math.cos(spread),
                side * (0.09 * k + leg * math.sin(spread)),
                leg,
                0.055 * k,
                side * spread,
                suit,
                legs_opacity,
                0.1,
            )
        )
        reach = math.radians(rng.uniform(55.0, 115.0))
        arm = float(rng.uniform(0.28, 0.34)) * k
        parts.append(
            Part(
                "ellipse",
                0.3 * k + arm * math.cos(reach),
                side * (0.16 * k + arm * math.sin(reach)),
                arm,
                0.04 * k,
                side * reach,
                arms,
                float(rng.uniform(0.45, 0.8)),
                0.1,
            )
        )
    parts.append(
        Part(
            "ellipse",
            0.08 * k,
            0.0,
            0.3 * k,
            (0.2 if life_jacket else 0.15) * k,
            0.0,
            torso,
            0.9 if life_jacket else float(rng.uniform(0.5, 0.8)),
            0.3,
        )
    )
    parts.append(Part("ellipse", 0.52 * k, 0.0, 0.11 * k, 0.095 * k, 0.0, cover, 0.9, 0.3))
    parts.append(Part("ellipse", 0.56 * k, 0.0, 0.06 * k, 0.06 * k, 0.0, skin, 0.8, 0.2))
    return parts


def boat_parts(rng: np.random.Generator, length: float, moving: bool) -> list[Part]:
    """Hull with a pointed bow, a console or cabin, and (when moving) a foam wake."""
    half, beam = length / 2, 0.19 * length
    hull = pick_colour(rng, HULL)
    cabin = pick_colour(rng, ((220, 220, 220), (70, 70, 75), (150, 150, 150)))
    parts: list[Part] = []
    foam = (235.0, 238.0, 235.0)
    if moving:
        parts.append(
            Part(
                "ellipse",
                -half - 1.4 * length,
                0.0,
                1.5 * length,
                0.55 * beam,
                0.0,
                foam,
                0.35,
                0.0,
                False,
            )
        )
        parts.append(
            Part("ellipse", 0.15 * half, 0.0, 0.95 * half, 1.35 * beam, 0.0, foam, 0.25, 0.0, False)
        )
    parts.append(Part("box", -0.35 * half, 0.0, 0.65 * half, beam, 0.0, hull, 1.0, 0.15))
    parts.append(Part("ellipse", 0.15 * half, 0.0, 0.85 * half, beam, 0.0, hull, 1.0, 0.15))
    parts.append(Part("box", -0.3 * half, 0.0, 0.3 * half, 0.6 * beam, 0.0, cabin, 1.0, 0.25))
    parts.append(
        Part("box", 0.05 * half, 0.0, 0.06 * half, 0.55 * beam, 0.0, (60, 55, 50), 0.9, 0.0)
    )
    return parts


def bird_parts(rng: np.random.Generator, span: float) -> list[Part]:
    """A gull seen from above: body, two flapping wings with dark tips."""
    body = (235.0, 235.0, 232.0)
    wing = pick_colour(rng, ((175, 175, 170), (230, 230, 228), (95, 95, 90)))
    half = span / 2
    parts = [Part("ellipse", 0.0, 0.0, 0.2 * span, 0.05 * span, 0.0, body, 1.0, 0.2)]
    for side in (-1.0, 1.0):
        parts.append(
            Part(
                "ellipse",
                0.02 * span,
                side * 0.04 * span,
                0.48 * half,
                0.075 * span,
                side * math.pi / 2,
                wing,
                1.0,
                0.2,
                True,
                "wing",
            )
        )
        parts.append(
            Part(
                "ellipse",
                0.0,
                side * 0.6 * half,
                0.2 * half,
                0.05 * span,
                side * math.pi / 2,
                (40, 40, 40),
                0.8,
                0.0,
                True,
                "wing",
            )
        )
    return parts


def debris_parts(rng: np.random.Generator, size: float) -> list[Part]:
    """One to three overlapping pieces (wood, foam, plastic) about ``size`` across."""
    parts = []
    for _ in range(int(rng.integers(1, 4))):
        a = size * rng.uniform(0.2, 0.5)
        parts.append(
            Part(
                "ellipse" if rng.random() < 0.6 else "box",
                float(rng.normal(0, 0.15 * size)),
                float(rng.normal(0, 0.15 * size)),
                a,
                a * rng.uniform(0.3, 0.9),
                float(rng.uniform(0, math.pi)),
                pick_colour(rng, DEBRIS),
                float(rng.uniform(0.7, 1.0)),
                0.2,
            )
        )
    return parts


MOORING_BUOY: tuple[BGR, ...] = (
    (20, 100, 245),
    (10, 140, 250),
    (30, 200, 240),
    (235, 235, 230),
    (40, 40, 200),
)


def mooring_buoy_parts(rng: np.random.Generator, diameter: float) -> list[Part]:
    """A round mooring buoy from above: a ring of disturbed water, the sphere darkening towards
    its rim, a highlight, and now and then the dark pick-up ring on its top."""
    r = diameter / 2
    colour = pick_colour(rng, MOORING_BUOY)
    parts = [
        Part("ellipse", 0.0, 0.0, 1.5 * r, 1.5 * r, 0.0, RIPPLE, 0.15, 0.0, False),
        Part("ellipse", 0.0, 0.0, r, r, 0.0, colour, 1.0, 0.5),
        Part("ellipse", 0.3 * r, -0.25 * r, 0.3 * r, 0.25 * r, 0.0, (250, 250, 250), 0.35, 0.0),
    ]
    if rng.random() < 0.4:
        parts.append(Part("ellipse", 0.0, 0.0, 0.2 * r, 0.2 * r, 0.0, (40, 40, 45), 0.9, 0.0))
    return parts


def add_mooring_buoys(objects: list[SceneObject], sc: Scenario) -> None:
    """Append the scenario's mooring buoys (their own generator: nothing else changes)."""
    rng = np.random.default_rng([sc.seed, 3])
    for _ in range(sc.n_mooring_buoys):
        objects.append(
            SceneObject(
                len(objects) + 1,
                "buoy",
                uniform_in(rng, sc.area_ne),
                float(rng.uniform(0, 2 * math.pi)),
                mooring_buoy_parts(rng, float(rng.uniform(0.4, 1.2))),
                wander_m=float(rng.uniform(0.3, 1.5)),
                wander_period_s=float(rng.uniform(20, 60)),
                bob_depth=float(rng.uniform(0.0, 0.15)),
                bob_period_s=float(rng.uniform(3.0, 7.0)),
                phase=float(rng.random()),
            )
        )


def car_parts(rng: np.random.Generator) -> list[Part]:
    """A car from above: body, dark windscreen and rear window, roof, shadow."""
    length, width = float(rng.uniform(3.9, 4.9)), float(rng.uniform(1.7, 1.95))
    body = pick_colour(rng, CAR)
    roof = tuple(0.9 * c for c in body)
    glass = (40.0, 35.0, 30.0)
    return [
        Part("box", -0.25, 0.35, length / 2, width / 2, 0.0, (20, 20, 20), 0.35, 0.0, False),
        Part("box", 0.0, 0.0, length / 2, width / 2, 0.0, body, 1.0, 0.2),
        Part("box", 0.2 * length, 0.0, 0.09 * length, 0.42 * width, 0.0, glass, 0.95, 0.0),
        Part("box", -0.27 * length, 0.0, 0.06 * length, 0.4 * width, 0.0, glass, 0.95, 0.0),
        Part("box", -0.03 * length, 0.0, 0.18 * length, 0.4 * width, 0.0, roof, 1.0, 0.1),
    ]


def pedestrian_parts(rng: np.random.Generator) -> list[Part]:
    """A person from above: shadow, shoulders in clothing colour, head, swinging arms."""
    shoulders = float(rng.uniform(0.2, 0.26))
    clothes = pick_colour(rng, CLOTHES)
    hair = pick_colour(rng, HAIR)
    return [
        Part("ellipse", -0.45, 0.3, 0.45, 0.14, 0.6, (15, 15, 15), 0.4, 0.0, False),
        Part("ellipse", 0.0, shoulders, 0.11, 0.045, 0.0, clothes, 0.9, 0.1, True, "limb", 0.15),
        Part(
            "ellipse",
            0.0,
            -shoulders,
            0.11,
            0.045,
            0.0,
            clothes,
            0.9,
            0.1,
            True,
            "limb",
            0.15,
            math.pi,
        ),
        Part("ellipse", 0.0, 0.0, 0.13, shoulders, 0.0, clothes, 1.0, 0.3),
        Part("ellipse", 0.01, 0.0, 0.1, 0.085, 0.0, hair, 1.0, 0.3),
    ]


def glint_parts(rng: np.random.Generator, size: float) -> list[Part]:
    """A sun glint: a bright core and a softer halo that flash together."""
    return [
        Part(
            "ellipse",
            0.0,
            0.0,
            1.8 * size,
            1.2 * size,
            0.0,
            (235, 245, 250),
            0.35,
            0.0,
            False,
            "glint",
        ),
        Part("ellipse", 0.0, 0.0, size, 0.6 * size, 0.0, (250, 253, 255), 1.0, 0.0, True, "glint"),
    ]


# ----------------------------------------------------------------------------- worlds


def build_world(scenario: Scenario) -> World:
    """Place every object of ``scenario`` (deterministic from its seed)."""
    if scenario.kind == "maritime":
        return World(scenario, _maritime_objects(scenario))
    if scenario.kind == "wild":
        from sim.wild import build_wild_world  # sim.wild builds on this module

        return build_wild_world(scenario)
    layout = _urban_layout(scenario)
    return World(scenario, _urban_objects(scenario, layout), layout)


def add_birds_debris_glints(
    objects: list[SceneObject],
    rng: np.random.Generator,
    sc: Scenario,
    diag: float,
    bob: float,
    drift: Callable[[], tuple[float, float]],
) -> None:
    """Append the scenario's birds, floating debris and sun glints to ``objects`` (shared by
    every maritime world, in this order, so a seed draws the same scene)."""
    for _ in range(sc.n_birds):
        heading = float(rng.uniform(0, 2 * math.pi))
        speed = float(rng.uniform(8.0, 15.0))
        objects.append(
            SceneObject(
                len(objects) + 1,
                "bird",
                loop_start(rng, sc.area_ne, heading, diag),
                heading,
                bird_parts(rng, float(rng.uniform(1.0, 1.5))),
                (speed * math.cos(heading), speed * math.sin(heading)),
                height_m=float(rng.uniform(5.0, 35.0)),
                loop_m=diag + 200.0,
                period_s=float(rng.uniform(0.25, 0.45)),
                phase=float(rng.random()),
            )
        )
    for _ in range(sc.n_debris):
        objects.append(
            SceneObject(
                len(objects) + 1,
                "debris",
                uniform_in(rng, sc.area_ne),
                float(rng.uniform(0, 2 * math.pi)),
                debris_parts(rng, float(rng.uniform(0.2, 1.0))),
                drift(),
                wander_m=float(rng.uniform(0.1, 0.5)),
                turn_rate=float(rng.normal(0, 0.03)),
                bob_depth=float(min(0.6, 0.5 * bob)),
                bob_period_s=float(rng.uniform(3.0, 7.0)),
                phase=float(rng.random()),
            )
        )
    for _ in range(sc.n_glints):
        objects.append(
            SceneObject(
                len(objects) + 1,
                "sun_glint",
                uniform_in(rng, sc.area_ne),
                float(rng.uniform(0, 2 * math.pi)),
                glint_parts(rng, float(rng.uniform(0.08, 0.3))),
                drift(),
                period_s=float(rng.uniform(0.4, 2.0)),
                duty=float(rng.uniform(0.15, 0.4)),
                phase=float(rng.random()),
            )
        )


def _maritime_objects(sc: Scenario) -> list[SceneObject]:
    rng = np.random.default_rng([sc.seed, 1])
    drift_dir = math.radians(sc.wind_from_deg + 180.0 + rng.normal(0, 25))
    objects: list[SceneObject] = []

    def drift() -> tuple[float, float]:
        speed = rng.uniform(*sc.drift_m_s)
        d = drift_dir + rng.normal(0, 0.3)
        return speed * math.cos(d), speed * math.sin(d)

    bob = 0.12 + 0.1 * sc.sea_state
    starfish_rng = np.random.default_rng([sc.seed, 2])
    for k in range(sc.n_swimmers + sc.n_life_jacket):
        jacket = k >= sc.n_swimmers
        u = rng.random()
        if jacket:
            pose = "float" if u < 0.5 else "tread"
        elif u < sc.head_only_fraction:
            pose = "head"
        elif u < sc.head_only_fraction + sc.floating_fraction:
            pose = "float"
        else:
            pose = "tread"
        size = {
            "head": rng.uniform(0.18, 0.26),
            "tread": rng.uniform(*sc.swimmer_width_m),
            "float": rng.uniform(1.3, 1.8),
        }[pose]
        if jacket and pose == "tread":
            size = rng.uniform(max(sc.swimmer_width_m[0], 0.5), max(sc.swimmer_width_m[1], 0.7))
        place = uniform_in(rng, sc.area_ne)
        heading = float(rng.uniform(0, 2 * math.pi))
        parts = swimmer_parts(rng, float(size), pose, jacket)  # drawn always: rng stays in step
        if pose == "float" and starfish_rng.random() < sc.starfish_fraction:
            parts = swimmer_parts(starfish_rng, float(size), "starfish", jacket)
        objects.append(
            SceneObject(
                len(objects) + 1,
                "swimmer_with_life_jacket" if jacket else "swimmer",
                place,
                heading,
                parts,
                drift(),
                wander_m=float(rng.uniform(0.2, 1.0)),
                wander_period_s=float(rng.uniform(30, 90)),
                turn_rate=float(rng.normal(0, 0.05)),
                period_s=float(rng.uniform(1.5, 3.0)),
                bob_depth=float(min(0.75, bob * rng.uniform(0.5, 1.5))),
                bob_period_s=float(rng.uniform(3.0, 7.0)),
                phase=float(rng.random()),
            )
        )
    n0, e0, n1, e1 = sc.area_ne
    diag = math.hypot(n1 - n0, e1 - e0)
    for _ in range(sc.n_boats):
        length = float(rng.uniform(4.0, 10.0))
        heading = float(rng.uniform(0, 2 * math.pi))
        speed = float(rng.uniform(2.0, 8.0))
        start = loop_start(rng, sc.area_ne, heading, diag)
        objects.append(
            SceneObject(
                len(objects) + 1,
                "boat",
                start,
                heading,
                boat_parts(rng, length, True),
                (speed * math.cos(heading), speed * math.sin(heading)),
                loop_m=diag + 200.0,
                phase=float(rng.random()),
            )
        )
    add_birds_debris_glints(objects, rng, sc, diag, bob, drift)
    add_mooring_buoys(objects, sc)
    return objects


def loop_start(
    rng: np.random.Generator, area: tuple[float, float, float, float], heading: float, diag: float
) -> tuple[float, float]:
    """Start of a straight loop through a random point of ``area`` along ``heading``."""
    pn, pe = uniform_in(rng, area)
    back = diag / 2 + 100.0
    return pn - back * math.cos(heading), pe - back * math.sin(heading)


def _urban_layout(sc: Scenario) -> UrbanLayout:
    rng = np.random.default_rng([sc.seed, 2])
    block, road = float(rng.uniform(55, 75)), float(rng.uniform(9, 13))
    n0, e0, n1, e1 = sc.area_ne
    origin = (n0 + float(rng.uniform(0, block)), e0 + float(rng.uniform(0, block)))
    layout = UrbanLayout(origin, block, road)
    margin = 120.0
    kmin_n = math.floor((n0 - margin - origin[0]) / block)
    kmax_n = math.ceil((n1 + margin - origin[0]) / block)
    kmin_e = math.floor((e0 - margin - origin[1]) / block)
    kmax_e = math.ceil((e1 + margin - origin[1]) / block)
    roofs = (
        (70, 80, 150),
        (60, 70, 120),
        (120, 120, 120),
        (80, 80, 85),
        (170, 170, 165),
        (55, 60, 70),
        (100, 115, 130),
    )
    inset = road / 2 + 2.5  # sidewalk
    for i in range(kmin_n, kmax_n):
        for j in range(kmin_e, kmax_e):
            bn0, be0 = origin[0] + i * block + inset, origin[1] + j * block + inset
            bn1, be1 = origin[0] + (i + 1) * block - inset, origin[1] + (j + 1) * block - inset
            u = rng.random()
            if u < 0.15:
                layout.parks.append((bn0, be0, bn1, be1))
                for _ in range(int(rng.integers(6, 18))):
                    layout.trees.append(
                        (
                            float(rng.uniform(bn0 + 2, bn1 - 2)),
                            float(rng.uniform(be0 + 2, be1 - 2)),
                            float(rng.uniform(1.5, 4.0)),
                        )
                    )
            elif u < 0.27:
                layout.lots.append((bn0, be0, bn1, be1))
            else:
                _split_block(rng, layout, (bn0, be0, bn1, be1), roofs)
    return layout


def _split_block(
    rng: np.random.Generator,
    layout: UrbanLayout,
    rect: tuple[float, float, float, float],
    roofs: tuple[BGR, ...],
) -> None:
    """Fill a block with 1-3 x 1-3 buildings separated by small yards."""
    bn0, be0, bn1, be1 = rect
    rows, cols = int(rng.integers(1, 4)), int(rng.integers(1, 4))
    dn, de = (bn1 - bn0) / rows, (be1 - be0) / cols
    for r in range(rows):
        for c in range(cols):
            gap = float(rng.uniform(1.0, 4.0))
            layout.buildings.append(
                Building(
                    (
                        bn0 + r * dn + gap,
                        be0 + c * de + gap,
                        bn0 + (r + 1) * dn - gap,
                        be0 + (c + 1) * de - gap,
                    ),
                    pick_colour(rng, roofs),
                    float(rng.uniform(6, 25)),
                )
            )
    if rng.random() < 0.5:
        layout.trees.append(
            (
                float(rng.uniform(bn0, bn1)),
                float(rng.uniform(be0, be1)),
                float(rng.uniform(1.5, 3.5)),
            )
        )


def _urban_objects(sc: Scenario, layout: UrbanLayout) -> list[SceneObject]:
    rng = np.random.default_rng([sc.seed, 3])
    objects: list[SceneObject] = []
    north_roads, east_roads = layout.road_lines(sc.area_ne)
    n0, e0, n1, e1 = sc.area_ne
    lane = layout.road_m / 4
    for _ in range(sc.n_parked_cars):
        if layout.lots and rng.random() < 0.5:
            ln0, le0, ln1, le1 = layout.lots[int(rng.integers(len(layout.lots)))]
            row = int(rng.integers(0, max(1, int((ln1 - ln0 - 4) / 6))))
            pos = (ln0 + 3 + 6 * row, float(rng.uniform(le0 + 2, le1 - 2)))
            heading = 0.0
        else:
            along_east = rng.random() < 0.5 and north_roads
            side = 1.0 if rng.random() < 0.5 else -1.0
            if along_east or not east_roads:
                rn = north_roads[int(rng.integers(len(north_roads)))] if north_roads else n0
                pos = (rn + side * (layout.road_m / 2 - 1.1), float(rng.uniform(e0, e1)))
                heading = math.pi / 2
            else:
                re_ = east_roads[int(rng.integers(len(east_roads)))]
                pos = (float(rng.uniform(n0, n1)), re_ + side * (layout.road_m / 2 - 1.1))
                heading = 0.0
        objects.append(
            SceneObject(len(objects) + 1, "car", pos, heading, car_parts(rng), static=True)
        )
    for _ in range(sc.n_moving_cars):
        speed = float(rng.uniform(5.0, 13.0))
        forward = 1.0 if rng.random() < 0.5 else -1.0
        if (rng.random() < 0.5 and north_roads) or not east_roads:
            rn = north_roads[int(rng.integers(len(north_roads)))] if north_roads else n0
            heading = math.pi / 2 if forward > 0 else -math.pi / 2
            start = (rn - forward * lane, e0 - 60.0 if forward > 0 else e1 + 60.0)
            length = e1 - e0 + 120.0
        else:
            re_ = east_roads[int(rng.integers(len(east_roads)))]
            heading = 0.0 if forward > 0 else math.pi
            start = (n0 - 60.0 if forward > 0 else n1 + 60.0, re_ + forward * lane)
            length = n1 - n0 + 120.0
        objects.append(
            SceneObject(
                len(objects) + 1,
                "car",
                start,
                heading,
                car_parts(rng),
                (speed * math.cos(heading), speed * math.sin(heading)),
                loop_m=length,
                phase=float(rng.random()),
            )
        )
    for _ in range(sc.n_pedestrians):
        speed = float(rng.uniform(0.7, 1.5))
        if layout.parks and rng.random() < 0.3:
            start = uniform_in(rng, layout.parks[int(rng.integers(len(layout.parks)))])
            heading = float(rng.uniform(0, 2 * math.pi))
        elif (rng.random() < 0.5 and north_roads) or not east_roads:
            rn = north_roads[int(rng.integers(len(north_roads)))] if north_roads else n0
            side = 1.0 if rng.random() < 0.5 else -1.0
            start = (rn + side * (layout.road_m / 2 + 1.2), float(rng.uniform(e0, e1)))
            heading = math.pi / 2 if rng.random() < 0.5 else -math.pi / 2
        else:
            re_ = east_roads[int(rng.integers(len(east_roads)))]
            side = 1.0 if rng.random() < 0.5 else -1.0
            start = (float(rng.uniform(n0, n1)), re_ + side * (layout.road_m / 2 + 1.2))
            heading = 0.0 if rng.random() < 0.5 else math.pi
        walking = rng.random() < 0.75
        objects.append(
            person_on_land(
                rng,
                len(objects) + 1,
                start,
                heading,
                pedestrian_parts(rng),
                speed if walking else 0.0,
                (15.0, 50.0),
            )
        )
    return objects


def person_on_land(
    rng: np.random.Generator,
    track_id: int,
    start: tuple[float, float],
    heading: float,
    parts: list[Part],
    speed: float,
    patrol_range_m: tuple[float, float],
) -> SceneObject:
    """A ``person`` walking back and forth along ``heading`` at ``speed`` over a patrol drawn
    from ``patrol_range_m`` (limbs swinging in step), or standing still when ``speed`` is 0;
    draws the patrol (walkers only), then the phase, from ``rng``."""
    walking = speed > 0
    return SceneObject(
        track_id,
        "person",
        start,
        heading,
        parts,
        (speed * math.cos(heading), speed * math.sin(heading)) if walking else (0.0, 0.0),
        patrol_m=float(rng.uniform(*patrol_range_m)) if walking else 0.0,
        period_s=1.1 / speed if walking else 4.0,
        phase=float(rng.random()),
    )
