"""Wild land: meadow, forest, rock, snow and sand, with people, animals and ground clutter.

Land search happens far from streets. A ``kind = "wild"`` :class:`~sim.scene.Scenario` names a
``biome`` (:data:`BIOMES`); the ground (:class:`WildGround`, painted once like the city) is two
ground tones blended by multi-scale noise, patches of a second material, a meandering trail,
and the biome's clutter with shadows cast away from the sun: tree crowns (dense canopy with
clearings in the forest, scattered elsewhere), bushes, boulders, fallen logs, scree, dune
ripples, ski and foot tracks. Much of that clutter is person-sized, which is the point.

Objects (:func:`wild_objects`): people walking along the trail or across open ground, standing,
sitting and lying still (``person``, the search targets), and animals grazing or walking
(``animal``, never a target). Everything follows from the scenario's seed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import cv2
import numpy as np

from sim.ground import PaintedGround
from sim.scene import (
    BGR,
    CLOTHES,
    HAIR,
    Part,
    Scenario,
    SceneObject,
    World,
    pedestrian_parts,
    person_on_land,
    pick_colour,
    uniform_in,
)


@dataclass(frozen=True)
class Biome:
    """Colours (BGR) and clutter densities (per hectare) of one kind of wild ground."""

    ground: tuple[BGR, BGR]
    patch: BGR
    trail: BGR
    crowns: tuple[BGR, ...]
    trees_per_ha: float
    bushes_per_ha: float
    rocks_per_ha: float
    logs_per_ha: float
    rock: BGR = (120.0, 124.0, 128.0)
    bush: BGR = (40.0, 92.0, 60.0)
    ripples: bool = False
    tracks: bool = False


BIOMES: dict[str, Biome] = {
    "meadow": Biome(
        ground=((70.0, 140.0, 95.0), (85.0, 165.0, 150.0)),
        patch=(80.0, 110.0, 130.0),
        trail=(95.0, 125.0, 150.0),
        crowns=((35.0, 85.0, 50.0), (45.0, 100.0, 65.0)),
        trees_per_ha=6.0,
        bushes_per_ha=40.0,
        rocks_per_ha=8.0,
        logs_per_ha=2.0,
    ),
    "forest": Biome(
        ground=((40.0, 72.0, 55.0), (50.0, 85.0, 95.0)),
        patch=(45.0, 70.0, 85.0),
        trail=(80.0, 105.0, 125.0),
        crowns=((30.0, 68.0, 40.0), (40.0, 88.0, 52.0), (34.0, 58.0, 46.0), (42.0, 90.0, 75.0)),
        trees_per_ha=260.0,
        bushes_per_ha=60.0,
        rocks_per_ha=6.0,
        logs_per_ha=25.0,
    ),
    "rock": Biome(
        ground=((118.0, 124.0, 128.0), (95.0, 110.0, 126.0)),
        patch=(70.0, 80.0, 88.0),
        trail=(140.0, 150.0, 158.0),
        crowns=((40.0, 80.0, 55.0),),
        trees_per_ha=2.0,
        bushes_per_ha=20.0,
        rocks_per_ha=160.0,
        logs_per_ha=0.0,
        rock=(135.0, 140.0, 145.0),
        bush=(55.0, 95.0, 80.0),
    ),
    "snow": Biome(
        ground=((238.0, 234.0, 230.0), (222.0, 210.0, 198.0)),
        patch=(200.0, 190.0, 182.0),
        trail=(215.0, 212.0, 210.0),
        crowns=((40.0, 60.0, 38.0), (48.0, 70.0, 45.0)),
        trees_per_ha=10.0,
        bushes_per_ha=5.0,
        rocks_per_ha=30.0,
        logs_per_ha=2.0,
        rock=(70.0, 72.0, 75.0),
        bush=(60.0, 70.0, 60.0),
        tracks=True,
    ),
    "sand": Biome(
        ground=((150.0, 190.0, 215.0), (128.0, 168.0, 198.0)),
        patch=(110.0, 150.0, 180.0),
        trail=(165.0, 200.0, 222.0),
        crowns=((50.0, 105.0, 80.0),),
        trees_per_ha=1.0,
        bushes_per_ha=25.0,
        rocks_per_ha=6.0,
        logs_per_ha=6.0,
        rock=(110.0, 130.0, 150.0),
        bush=(60.0, 110.0, 100.0),
        ripples=True,
    ),
}
#: Coats of animals seen from above (BGR): brown, dark, white, grey, tan.
COATS: tuple[BGR, ...] = (
    (40.0, 70.0, 110.0),
    (30.0, 30.0, 35.0),
    (225.0, 228.0, 230.0),
    (120.0, 122.0, 125.0),
    (80.0, 130.0, 170.0),
)
LOG = (55.0, 80.0, 105.0)


def biome_of(scenario: Scenario) -> Biome:
    """The scenario's biome (``ValueError`` naming the known ones)."""
    try:
        return BIOMES[scenario.biome]
    except KeyError:
        raise ValueError(f"unknown biome {scenario.biome!r}; known: {', '.join(BIOMES)}") from None


# ----------------------------------------------------------------------------------- objects


def lying_parts(rng: np.random.Generator) -> list[Part]:
    """A person lying on the ground: body and legs in clothing colour, head, arms at the sides."""
    length = float(rng.uniform(1.55, 1.85))
    clothes, legs = pick_colour(rng, CLOTHES), pick_colour(rng, CLOTHES)
    hair = pick_colour(rng, HAIR)
    half = length / 2
    return [
        Part("ellipse", -0.05, 0.12, half, 0.2, 0.0, (15, 15, 15), 0.3, 0.0, False),
        Part("ellipse", -0.45 * half, 0.0, 0.5 * half, 0.15, 0.0, legs, 1.0, 0.25),
        Part("ellipse", 0.25 * half, 0.0, 0.42 * half, 0.22, 0.0, clothes, 1.0, 0.3),
        Part("ellipse", 0.25 * half, 0.27, 0.35 * half, 0.05, 0.1, clothes, 0.9, 0.2),
        Part("ellipse", 0.25 * half, -0.27, 0.35 * half, 0.05, -0.1, clothes, 0.9, 0.2),
        Part("ellipse", half - 0.1, 0.0, 0.11, 0.09, 0.0, hair, 1.0, 0.3),
    ]


def sitting_parts(rng: np.random.Generator) -> list[Part]:
    """A person sitting, seen from above: shoulders and head over folded legs."""
    clothes, legs = pick_colour(rng, CLOTHES), pick_colour(rng, CLOTHES)
    hair = pick_colour(rng, HAIR)
    return [
        Part("ellipse", -0.2, 0.2, 0.35, 0.14, 0.5, (15, 15, 15), 0.35, 0.0, False),
        Part("ellipse", 0.25, 0.0, 0.25, 0.17, 0.0, legs, 1.0, 0.25),
        Part("ellipse", 0.0, 0.0, 0.13, 0.23, 0.0, clothes, 1.0, 0.3),
        Part("ellipse", 0.01, 0.0, 0.1, 0.085, 0.0, hair, 1.0, 0.3),
    ]


def animal_parts(rng: np.random.Generator) -> list[Part]:
    """A four-legged animal from above (deer, sheep, cow, dog): body, neck and head, shadow."""
    length = float(rng.uniform(0.7, 2.0))
    half, width = length / 2, length * float(rng.uniform(0.25, 0.35))
    coat = pick_colour(rng, COATS)
    head = tuple(0.8 * c for c in coat)
    return [
        Part(
            "ellipse",
            -0.1 * length,
            0.15 * width,
            half,
            0.6 * width,
            0.0,
            (15, 15, 15),
            0.35,
            0.0,
            False,
        ),
        Part("ellipse", 0.0, 0.0, half, width / 2, 0.0, coat, 1.0, 0.3),
        Part(
            "ellipse", half + 0.12 * length, 0.0, 0.14 * length, 0.22 * width, 0.0, head, 1.0, 0.25
        ),
    ]


def _open_ground(rng: np.random.Generator, sc: Scenario, trail: np.ndarray) -> tuple[float, float]:
    """A place for a person: on the trail half the time, anywhere in the area otherwise."""
    if rng.random() < 0.5:
        k = int(rng.integers(len(trail)))
        n, e = trail[k]
        return float(n + rng.normal(0, 1.0)), float(e + rng.normal(0, 1.0))
    return uniform_in(rng, sc.area_ne)


def trail_points(sc: Scenario) -> np.ndarray:
    """``[K, 2]`` north/east of the meandering trail across the area (every 2 m)."""
    rng = np.random.default_rng([sc.seed, 41])
    n0, e0, n1, e1 = sc.area_ne
    along = np.arange(n0 - 120.0, n1 + 120.0, 2.0)
    wiggle = np.zeros_like(along)
    for _ in range(3):
        wavelength = float(rng.uniform(60.0, 250.0))
        wiggle += float(rng.uniform(5.0, 25.0)) * np.sin(
            2 * np.pi * along / wavelength + float(rng.uniform(0, 2 * np.pi))
        )
    east = float(rng.uniform(e0 + 0.2 * (e1 - e0), e1 - 0.2 * (e1 - e0))) + wiggle
    return np.stack([along, east], axis=1)


def wild_objects(sc: Scenario) -> list[SceneObject]:
    """People (walking, standing, sitting, lying) and animals of a wild scenario."""
    rng = np.random.default_rng([sc.seed, 43])
    trail = trail_points(sc)
    objects: list[SceneObject] = []
    for _ in range(sc.n_pedestrians):
        start = _open_ground(rng, sc, trail)
        heading = float(rng.uniform(0, 2 * math.pi))
        pose = rng.choice(["walking", "standing", "sitting", "lying"], p=[0.4, 0.3, 0.15, 0.15])
        speed = float(rng.uniform(0.6, 1.5)) if pose == "walking" else 0.0
        parts = {
            "walking": pedestrian_parts,
            "standing": pedestrian_parts,
            "sitting": sitting_parts,
            "lying": lying_parts,
        }[str(pose)](rng)
        objects.append(
            person_on_land(rng, len(objects) + 1, start, heading, parts, speed, (10.0, 40.0))
        )
    for _ in range(sc.n_animals):
        start = uniform_in(rng, sc.area_ne)
        heading = float(rng.uniform(0, 2 * math.pi))
        moving = rng.random() < 0.4
        speed = float(rng.uniform(0.3, 1.2)) if moving else 0.0
        objects.append(
            SceneObject(
                len(objects) + 1,
                "animal",
                start,
                heading,
                animal_parts(rng),
                (speed * math.cos(heading), speed * math.sin(heading)),
                patrol_m=float(rng.uniform(5, 25)) if moving else 0.0,
                static=not moving,
            )
        )
    return objects


def build_wild_world(scenario: Scenario) -> World:
    """The objects of a wild scenario (its ground is painted by :class:`WildGround`)."""
    biome_of(scenario)
    return World(scenario, wild_objects(scenario))


# ------------------------------------------------------------------------------------ ground


def _noise(rng: np.random.Generator, rows: int, cols: int, cell: float) -> np.ndarray:
    """Smooth noise (zero mean, about unit spread) with features about ``cell`` texels wide."""
    gr, gc = int(rows / cell) + 3, int(cols / cell) + 3
    coarse = rng.standard_normal((gr, gc)).astype(np.float32)
    return cv2.resize(coarse, (cols, rows), interpolation=cv2.INTER_CUBIC)


def _jitter(rng: np.random.Generator, bgr: BGR, spread: float = 10.0) -> tuple[float, ...]:
    """``bgr`` brighter or darker by about ``spread``, with a little tint."""
    level = rng.normal(0, spread)
    return tuple(float(np.clip(c + level + rng.normal(0, 0.25 * spread), 0, 255)) for c in bgr)


class WildGround(PaintedGround):
    """The painted wild ground of one ``kind = "wild"`` :class:`World` (module docstring)."""

    def _paint(self, world: World, rows: int, cols: int, rng: np.random.Generator) -> np.ndarray:
        sc = world.scenario
        biome = biome_of(sc)
        per_m = 1.0 / self.texel_m
        # ground tones blended by noise at 25 m and 4 m, patches of a second material
        blend = 0.6 * _noise(rng, rows, cols, 25 * per_m) + 0.4 * _noise(rng, rows, cols, 4 * per_m)
        t = np.clip(0.5 + 0.35 * blend, 0.0, 1.0)[..., None]
        a, b = (np.array(c, np.float32) for c in biome.ground)
        img = a * (1 - t) + b * t
        patch = _noise(rng, rows, cols, 8 * per_m) > 1.0
        img[patch] = 0.5 * img[patch] + 0.5 * np.array(biome.patch, np.float32)
        img = img.astype(np.uint8)
        self._paint_trail(img, sc, biome, rng)
        if biome.ripples:
            self._paint_ripples(img, rng)
        if biome.tracks:
            self._paint_tracks(img, biome, rng)
        area_ha = rows * cols * self.texel_m**2 / 1e4
        shadow = np.zeros((rows, cols), np.uint8)
        away = -sc.sun_direction_ned[:2] / max(float(np.hypot(*sc.sun_direction_ned[:2])), 1e-9)
        length_per_m = 1.0 / max(math.tan(math.radians(sc.sun_elevation_deg)), 0.05)

        def count(per_ha: float) -> int:
            return int(rng.poisson(per_ha * area_ha))

        rocks = [self._rock(rng, rows, cols, biome) for _ in range(count(biome.rocks_per_ha))]
        logs = [self._log(rng, rows, cols) for _ in range(count(biome.logs_per_ha))]
        bushes = [
            (float(rng.uniform(0, cols)), float(rng.uniform(0, rows)), float(rng.uniform(0.3, 1.4)))
            for _ in range(count(biome.bushes_per_ha))
        ]
        trees = [
            (float(rng.uniform(0, cols)), float(rng.uniform(0, rows)), float(rng.uniform(1.8, 5.0)))
            for _ in range(count(biome.trees_per_ha))
        ]
        # shadows first (away from the sun, by the clutter's height), then the clutter itself
        for c, r, radius in bushes:
            self._shadow_disc(shadow, c, r, radius, 1.2 * radius, away, length_per_m)
        for c, r, radius in trees:
            self._shadow_disc(shadow, c, r, radius, 2.5 * radius, away, length_per_m)
        for pts, _, height in rocks:
            off = np.array([away[1], -away[0]]) * height * length_per_m * per_m
            cv2.fillPoly(shadow, [np.round(pts + off).astype(np.int32)], 255)
        shadow = cv2.GaussianBlur(shadow, (0, 0), 0.25 * per_m)
        img = (img.astype(np.float32) * (1.0 - 0.45 * shadow[..., None] / 255.0)).astype(np.uint8)
        for pts, colour, _ in rocks:
            self._paint_rock(img, pts, colour)
        for pts, colour in logs:
            cv2.fillPoly(img, [pts], colour, cv2.LINE_AA)
        for c, r, radius in bushes:
            self._crown(img, rng, c, r, radius * per_m, _jitter(rng, biome.bush))
        for c, r, radius in trees:
            self._crown(img, rng, c, r, radius * per_m, pick_colour(rng, biome.crowns))
        grain = _noise(rng, rows, cols, 2.0)
        img = np.clip(img.astype(np.float32) * (1.0 + 0.07 * grain[..., None]), 0, 255)
        img = img.astype(np.uint8)
        self._paint_static(img, world)
        return img

    # -- clutter ----------------------------------------------------------------------------
    def _paint_trail(
        self, img: np.ndarray, sc: Scenario, biome: Biome, rng: np.random.Generator
    ) -> None:
        pts = np.array([self.texel(n, e) for n, e in trail_points(sc)], np.int32)
        width = int(float(rng.uniform(1.2, 3.0)) / self.texel_m)
        cv2.polylines(img, [pts], False, biome.trail, width, cv2.LINE_AA)

    def _paint_ripples(self, img: np.ndarray, rng: np.random.Generator) -> None:
        """Dune ripples: a faint grating 0.3-0.8 m apart, bent by noise."""
        rows, cols = img.shape[:2]
        y, x = np.mgrid[0:rows, 0:cols].astype(np.float32)
        theta = float(rng.uniform(0, math.pi))
        period = float(rng.uniform(0.3, 0.8)) / self.texel_m
        bend = 6.0 * _noise(rng, rows, cols, 150.0)
        wave = np.sin(2 * np.pi * (x * math.cos(theta) + y * math.sin(theta) + bend) / period)
        img[:] = np.clip(img.astype(np.float32) * (1.0 + 0.06 * wave[..., None]), 0, 255)

    def _paint_tracks(self, img: np.ndarray, biome: Biome, rng: np.random.Generator) -> None:
        """Ski and foot tracks: thin darker lines crossing the snow."""
        rows, cols = img.shape[:2]
        shade = tuple(0.85 * c for c in biome.ground[1])
        for _ in range(int(rng.integers(3, 9))):
            p0 = (int(rng.uniform(0, cols)), int(rng.uniform(0, rows)))
            angle = float(rng.uniform(0, 2 * math.pi))
            length = float(rng.uniform(200, 3000))
            p1 = (int(p0[0] + length * math.cos(angle)), int(p0[1] + length * math.sin(angle)))
            for offset in (-1.0, 1.0):
                d = (int(offset * 1.5 * math.sin(angle)), int(-offset * 1.5 * math.cos(angle)))
                cv2.line(img, (p0[0] + d[0], p0[1] + d[1]), (p1[0] + d[0], p1[1] + d[1]), shade, 1)

    def _rock(
        self, rng: np.random.Generator, rows: int, cols: int, biome: Biome
    ) -> tuple[np.ndarray, tuple[float, ...], float]:
        """A boulder outline (texels), its colour and its height in metres."""
        size = float(np.exp(rng.uniform(math.log(0.25), math.log(2.5)))) / self.texel_m
        c, r = rng.uniform(0, cols), rng.uniform(0, rows)
        angles = np.sort(rng.uniform(0, 2 * np.pi, int(rng.integers(5, 10))))
        radii = size / 2 * rng.uniform(0.6, 1.0, len(angles))
        pts = np.stack([c + radii * np.cos(angles), r + radii * np.sin(angles)], axis=1)
        return pts, _jitter(rng, biome.rock, 14.0), 0.4 * size * self.texel_m

    def _paint_rock(self, img: np.ndarray, pts: np.ndarray, colour: tuple[float, ...]) -> None:
        """The boulder, with a lit half and a darker half."""
        outline = np.round(pts).astype(np.int32)
        cv2.fillPoly(img, [outline], colour, cv2.LINE_AA)
        centre = pts.mean(axis=0)
        lit = np.round(centre + 0.55 * (pts - centre) - np.array([0.15, 0.15]) * np.ptp(pts, 0))
        cv2.fillPoly(img, [lit.astype(np.int32)], tuple(min(255.0, 1.15 * v) for v in colour))

    def _log(self, rng: np.random.Generator, rows: int, cols: int) -> tuple[np.ndarray, BGR]:
        """A fallen log: a long thin box 2-7 m by 0.2-0.5 m (texels) and its colour."""
        length = float(rng.uniform(2.0, 7.0)) / self.texel_m
        width = float(rng.uniform(0.2, 0.5)) / self.texel_m
        c, r, angle = rng.uniform(0, cols), rng.uniform(0, rows), rng.uniform(0, 2 * np.pi)
        box = cv2.boxPoints(((c, r), (length, width), math.degrees(angle)))
        return np.round(box).astype(np.int32), _jitter(rng, LOG, 12.0)

    def _shadow_disc(
        self,
        shadow: np.ndarray,
        c: float,
        r: float,
        radius_m: float,
        height_m: float,
        away: np.ndarray,
        length_per_m: float,
    ) -> None:
        off = height_m * length_per_m / self.texel_m
        # north/east -> texel column (east) and row (south); the shadow reaches from the foot
        # of the crown to where the sun throws its top
        foot = (int(c), int(r))
        tip = (int(c + away[1] * off), int(r - away[0] * off))
        radius = max(1, int(radius_m / self.texel_m))
        cv2.line(shadow, foot, tip, 255, 2 * radius)
        cv2.circle(shadow, tip, radius, 255, -1)

    def _crown(
        self,
        img: np.ndarray,
        rng: np.random.Generator,
        c: float,
        r: float,
        radius: float,
        colour: tuple[float, ...],
    ) -> None:
        """A tree crown or bush: a disc with a few lighter and darker lobes."""
        cv2.circle(img, (int(c), int(r)), max(1, int(radius)), colour, -1, cv2.LINE_AA)
        for _ in range(3):
            gain = float(rng.uniform(0.75, 1.3))
            lobe = tuple(float(np.clip(v * gain, 0, 255)) for v in colour)
            dc, dr = rng.normal(0, 0.35 * radius, 2)
            cv2.circle(
                img, (int(c + dc), int(r + dr)), max(1, int(0.45 * radius)), lobe, -1, cv2.LINE_AA
            )
