"""Body models seen from above: swimmers, people on land, and the things mistaken for them.

Each model is a function of its appearance (drawn once per object) and time (arm strokes, wing
beats, bobbing); it returns shapes in the object's own frame (:mod:`heldout.shapes`). Colours are
linear BGR reflectances.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from heldout.shapes import BGR, Capsule, Ellipse, Polygon, Shape, mix

SKIN: tuple[BGR, ...] = (
    (0.36, 0.45, 0.62),
    (0.25, 0.33, 0.50),
    (0.13, 0.19, 0.32),
    (0.06, 0.09, 0.16),
)
HAIR: tuple[BGR, ...] = (
    (0.02, 0.02, 0.025),
    (0.03, 0.05, 0.09),
    (0.08, 0.16, 0.30),
    (0.20, 0.36, 0.50),
    (0.30, 0.30, 0.30),
)
CAPS: tuple[BGR, ...] = (
    (0.80, 0.80, 0.80),
    (0.10, 0.10, 0.70),
    (0.70, 0.35, 0.05),
    (0.05, 0.60, 0.75),
    (0.05, 0.05, 0.05),
)
CLOTHES: tuple[BGR, ...] = (
    (0.03, 0.03, 0.03),
    (0.20, 0.08, 0.03),
    (0.08, 0.25, 0.10),
    (0.10, 0.10, 0.45),
    (0.50, 0.50, 0.50),
    (0.08, 0.15, 0.20),
    (0.55, 0.30, 0.10),
    (0.05, 0.45, 0.65),
    (0.70, 0.70, 0.72),
)
VESTS: tuple[BGR, ...] = (
    (0.02, 0.25, 0.85),
    (0.03, 0.10, 0.75),
    (0.02, 0.60, 0.85),
    (0.05, 0.40, 0.80),
)
BUOYS: tuple[BGR, ...] = (
    (0.02, 0.22, 0.80),
    (0.03, 0.08, 0.70),
    (0.03, 0.60, 0.85),
    (0.75, 0.75, 0.75),
)
FOAM: BGR = (0.62, 0.66, 0.68)


@dataclass(frozen=True)
class Look:
    """Appearance drawn once per object: colours, sizes, rhythm."""

    kind: str
    posture: str
    colours: tuple[BGR, ...]
    scale: float
    rate_hz: float
    phase: float
    submersion: float


def draw_look(rng: np.random.Generator, kind: str, water: BGR) -> Look:
    """A random appearance for an object of ``kind``."""

    def pick(options: tuple[BGR, ...]) -> BGR:
        return options[int(rng.integers(len(options)))]

    if kind in ("swimmer", "swimmer_with_life_jacket"):
        posture = str(rng.choice(["head", "upright", "upright", "back", "crawl"]))
        head = pick(CAPS) if rng.random() < 0.3 else pick(HAIR)
        colours = (pick(SKIN), head, pick(CLOTHES), pick(VESTS), water)
        submersion = float(rng.uniform(0.25, 0.65))
    elif kind == "person":
        posture = str(rng.choice(["standing", "standing", "walking", "lying", "sitting"]))
        colours = (pick(SKIN), pick(HAIR), pick(CLOTHES), pick(CLOTHES), pick(CLOTHES))
        submersion = 0.0
    elif kind == "buoy":
        posture, colours, submersion = "float", (pick(BUOYS), water), 0.0
    elif kind == "debris":
        posture = str(rng.choice(["plank", "bottle", "foam_block", "weed"]))
        colours = (
            {
                "plank": (0.10, 0.20, 0.30),
                "bottle": pick(((0.7, 0.7, 0.7), (0.2, 0.45, 0.2))),
                "foam_block": (0.75, 0.78, 0.78),
                "weed": (0.02, 0.07, 0.06),
            }[posture],
            water,
        )
        submersion = float(rng.uniform(0.0, 0.4))
    elif kind == "bird":
        posture = str(rng.choice(["flying", "flying", "sitting"]))
        colours = (
            pick(((0.75, 0.75, 0.75), (0.45, 0.45, 0.45), (0.05, 0.05, 0.05))),
            (0.05, 0.05, 0.05),
            (0.05, 0.45, 0.75),
        )
        submersion = 0.0
    elif kind == "boat":
        posture = "motor"
        colours = (
            pick(((0.80, 0.80, 0.78), (0.05, 0.08, 0.60), (0.45, 0.20, 0.05), (0.03, 0.40, 0.80))),
            (0.30, 0.30, 0.30),
            (0.03, 0.03, 0.03),
        )
        submersion = 0.0
    elif kind == "rock":
        posture = "rock"
        grey = float(rng.uniform(0.12, 0.35))
        colours = ((grey * 0.95, grey, grey * 1.05), (0.02, 0.02, 0.02))
        submersion = 0.0
    elif kind == "log":
        posture, colours, submersion = "log", ((0.06, 0.12, 0.18),), 0.0
    elif kind == "animal":
        posture = "grazing"
        colours = (pick(((0.55, 0.58, 0.60), (0.05, 0.12, 0.22), (0.03, 0.03, 0.03))),)
        submersion = 0.0
    else:
        raise ValueError(f"no body model for {kind!r}")
    return Look(
        kind,
        posture,
        colours,
        float(rng.uniform(0.9, 1.1)),
        float(rng.uniform(0.4, 1.2)),
        float(rng.uniform(0, 2 * math.pi)),
        submersion,
    )


def _swimmer(look: Look, t: float, lifted: float, jacket: bool) -> list[Shape]:
    skin, head, cloth, vest, water = look.colours
    s = look.scale
    wet = float(np.clip(look.submersion - 0.5 * lifted - (0.2 if jacket else 0.0), 0.05, 0.9))
    swing = math.sin(2 * math.pi * look.rate_hz * t + look.phase)
    shapes: list[Shape] = [Ellipse((0, 0), (0.45 * s, 0.38 * s), FOAM, 0.08, solid=False)]
    if look.posture in ("back", "crawl"):
        face_up = look.posture == "back"
        shapes.append(Ellipse((0, -0.25 * s), (0.45 * s, 1.05 * s), FOAM, 0.06, solid=False))
        for side in (-1, 1):
            shapes.append(
                Capsule(
                    (0.09 * side * s, -0.05 * s),
                    (0.13 * side * s, -0.85 * s),
                    0.07 * s,
                    mix(cloth if face_up else skin, water, wet + 0.2),
                    0.8,
                )
            )
            reach = 0.7 * s * (swing * side if not face_up else 1.0)
            end = (
                0.3 * side * s + (0.45 * s if face_up else 0.0) * side,
                0.35 * s + (reach if not face_up else 0.1 * s * swing),
            )
            shapes.append(
                Capsule((0.2 * side * s, 0.3 * s), end, 0.055 * s, mix(skin, water, wet), 0.85)
            )
        shapes.append(Ellipse((0, 0.15 * s), (0.2 * s, 0.3 * s), mix(cloth, water, wet * 0.7)))
        if jacket:
            shapes.append(Ellipse((0, 0.2 * s), (0.24 * s, 0.26 * s), vest))
        shapes.append(Ellipse((0, 0.55 * s), (0.09 * s, 0.11 * s), skin if face_up else head))
        return shapes
    if look.posture == "upright":
        for side in (-1, 1):
            angle = math.radians(25 * swing * side)
            shapes.append(
                Capsule(
                    (0.19 * side * s, 0.0),
                    (
                        side * (0.19 + 0.45 * math.cos(angle)) * s,
                        0.45 * math.sin(angle) * s + 0.1 * s,
                    ),
                    0.05 * s,
                    mix(skin, water, min(0.9, wet + 0.3)),
                    0.75,
                    solid=False,
                )
            )
        shapes.append(Ellipse((0, -0.02 * s), (0.24 * s, 0.11 * s), mix(cloth, water, wet)))
        if jacket:
            shapes.append(Ellipse((0, -0.01 * s), (0.27 * s, 0.16 * s), vest))
            shapes.append(Ellipse((0, 0.0), (0.1 * s, 0.08 * s), mix(cloth, water, wet)))
    elif jacket:
        shapes.append(Ellipse((0, 0.0), (0.22 * s, 0.15 * s), vest))
    shapes.append(Ellipse((0, 0.03 * s), (0.085 * s, 0.105 * s), skin))
    shapes.append(Ellipse((0, 0.0), (0.08 * s, 0.085 * s), head))
    return shapes


def _person(look: Look, t: float, sun_in_body_deg: float, sun_elevation_deg: float) -> list[Shape]:
    skin, hair, top, bottom, bag = look.colours
    s = look.scale
    away = math.radians(sun_in_body_deg + 180.0)
    drop = (
        (0.25 if look.posture in ("lying", "sitting") else 1.7)
        * s
        / math.tan(math.radians(max(sun_elevation_deg, 8.0)))
    )
    shapes: list[Shape] = []
    if look.posture == "lying":
        shapes.append(
            Ellipse(
                (0.12 * math.sin(away), 0.12 * math.cos(away)),
                (0.28 * s, 0.95 * s),
                (0.0, 0.0, 0.0),
                0.45,
                solid=False,
            )
        )
        for side in (-1, 1):
            shapes.append(
                Capsule((0.1 * side * s, -0.1 * s), (0.12 * side * s, -0.9 * s), 0.07 * s, bottom)
            )
            shapes.append(
                Capsule((0.2 * side * s, 0.45 * s), (0.3 * side * s, -0.05 * s), 0.05 * s, top)
            )
        shapes.append(Ellipse((0, 0.2 * s), (0.2 * s, 0.32 * s), top))
        shapes.append(Ellipse((0, 0.68 * s), (0.09 * s, 0.11 * s), hair))
        return shapes
    cx, cy = 0.5 * drop * math.sin(away), 0.5 * drop * math.cos(away)
    shapes.append(
        Ellipse(
            (cx, cy),
            (0.22 * s, 0.5 * drop + 0.12 * s),
            (0.0, 0.0, 0.0),
            0.5,
            angle_deg=-math.degrees(away),
            solid=False,
        )
    )
    if look.posture == "walking":
        stride = 0.3 * s * math.sin(2 * math.pi * 0.9 * t + look.phase)
        for side in (-1, 1):
            shapes.append(
                Capsule((0.1 * side * s, 0), (0.1 * side * s, stride * side), 0.07 * s, bottom)
            )
    if look.posture == "sitting":
        shapes.append(Capsule((-0.1 * s, 0.05 * s), (-0.1 * s, 0.5 * s), 0.07 * s, bottom))
        shapes.append(Capsule((0.1 * s, 0.05 * s), (0.1 * s, 0.5 * s), 0.07 * s, bottom))
    shapes.append(Ellipse((0, 0), (0.23 * s, 0.13 * s), top))
    if look.rate_hz > 0.9:
        shapes.append(
            Polygon(
                (
                    (-0.15 * s, -0.05 * s),
                    (0.15 * s, -0.05 * s),
                    (0.13 * s, -0.22 * s),
                    (-0.13 * s, -0.22 * s),
                ),
                bag,
            )
        )
    shapes.append(Ellipse((0, 0.02 * s), (0.09 * s, 0.1 * s), hair))
    return shapes


def shapes_at(
    look: Look,
    t: float,
    lifted: float = 0.0,
    sun_in_body_deg: float = 0.0,
    sun_elevation_deg: float = 45.0,
) -> list[Shape]:
    """The object's shapes at time ``t``; ``lifted`` (-1..1) is how far the swell raises it."""
    s = look.scale
    if look.kind in ("swimmer", "swimmer_with_life_jacket"):
        return _swimmer(look, t, lifted, look.kind == "swimmer_with_life_jacket")
    if look.kind == "person":
        return _person(look, t, sun_in_body_deg, sun_elevation_deg)
    if look.kind == "buoy":
        colour, water = look.colours
        r = 0.3 * s
        return [
            Ellipse((0, 0), (1.5 * r, 1.5 * r), FOAM, 0.08, solid=False),
            Ellipse((0, 0), (r, r), mix(colour, water, 0.15 - 0.1 * lifted)),
            Ellipse((-0.3 * r, 0.3 * r), (0.3 * r, 0.25 * r), (0.9, 0.9, 0.9), 0.6),
        ]
    if look.kind == "debris":
        colour, water = look.colours
        c = mix(colour, water, look.submersion)
        if look.posture == "plank":
            return [
                Polygon(
                    (
                        (-0.12 * s, -0.9 * s),
                        (0.12 * s, -0.9 * s),
                        (0.1 * s, 0.9 * s),
                        (-0.13 * s, 0.85 * s),
                    ),
                    c,
                )
            ]
        if look.posture == "bottle":
            return [Capsule((0, -0.12 * s), (0, 0.12 * s), 0.04 * s, c)]
        if look.posture == "foam_block":
            return [
                Polygon(
                    (
                        (-0.3 * s, -0.2 * s),
                        (0.25 * s, -0.25 * s),
                        (0.3 * s, 0.15 * s),
                        (0.0, 0.3 * s),
                        (-0.28 * s, 0.18 * s),
                    ),
                    c,
                )
            ]
        return [
            Polygon(
                (
                    (-1.2 * s, -0.3 * s),
                    (-0.2 * s, -0.8 * s),
                    (1.0 * s, -0.4 * s),
                    (1.3 * s, 0.5 * s),
                    (0.1 * s, 0.9 * s),
                    (-0.9 * s, 0.6 * s),
                ),
                c,
                0.75,
            )
        ]
    if look.kind == "bird":
        body, dark, beak = look.colours
        shapes: list[Shape] = [
            Ellipse((0, 0), (0.07 * s, 0.22 * s), body),
            Ellipse((0, 0.2 * s), (0.045 * s, 0.06 * s), body),
            Ellipse((0, 0.27 * s), (0.012 * s, 0.03 * s), beak),
        ]
        if look.posture == "flying":
            span = 0.7 * s * (0.55 + 0.45 * math.cos(2 * math.pi * 3.0 * t + look.phase))
            for side in (-1, 1):
                shapes.insert(
                    0,
                    Polygon(
                        (
                            (0.0, 0.08 * s),
                            (side * span, 0.0),
                            (side * span * 0.95, -0.06 * s),
                            (0.0, -0.06 * s),
                        ),
                        mix(body, dark, 0.3),
                    ),
                )
        return shapes
    if look.kind == "boat":
        hull, deck, motor = look.colours
        length, beam = 4.5 * s, 1.8 * s
        return [
            Polygon(
                ((-0.6 * beam, -0.5 * length), (0, -1.6 * length), (0.6 * beam, -0.5 * length)),
                FOAM,
                0.35,
                solid=False,
            ),
            Polygon(
                (
                    (-beam / 2, -length / 2),
                    (beam / 2, -length / 2),
                    (beam / 2, length / 6),
                    (0, length / 2),
                    (-beam / 2, length / 6),
                ),
                hull,
            ),
            Polygon(
                (
                    (-beam / 3, -length / 2.5),
                    (beam / 3, -length / 2.5),
                    (beam / 3, length / 8),
                    (-beam / 3, length / 8),
                ),
                deck,
            ),
            Ellipse((0, -length / 2 - 0.1), (0.15 * s, 0.2 * s), motor),
        ]
    if look.kind == "rock":
        grey, shade = look.colours
        r = 0.6 * s
        pts = tuple(
            (
                r * math.cos(a) * (0.8 + 0.3 * math.sin(3 * a + look.phase)),
                r * math.sin(a) * (0.7 + 0.3 * math.cos(2 * a + look.phase)),
            )
            for a in np.linspace(0, 2 * math.pi, 9)[:-1]
        )
        return [
            Polygon(tuple((x + 0.25 * r, y - 0.25 * r) for x, y in pts), shade, 0.5, solid=False),
            Polygon(pts, grey),
        ]
    if look.kind == "log":
        return [Capsule((0, -1.2 * s), (0, 1.2 * s), 0.15 * s, look.colours[0])]
    if look.kind == "animal":
        coat = look.colours[0]
        return [
            Ellipse((0.2, -0.2), (0.3 * s, 0.6 * s), (0.0, 0.0, 0.0), 0.4, solid=False),
            Ellipse((0, 0), (0.25 * s, 0.55 * s), coat),
            Ellipse((0, 0.62 * s), (0.1 * s, 0.16 * s), coat),
        ]
    raise ValueError(f"no body model for {look.kind!r}")
