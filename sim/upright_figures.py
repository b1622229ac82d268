"""Figures with height, at the sizes of real maritime footage: each returns its flat parts (on
the water or ground plane, :class:`sim.scene.Part`) and its upright parts
(:class:`sim.scene.Upright`).

Sizes follow the SeaDronesSee v2 validation boxes (docs/sim_vs_real.md): a swimmer's box is
0.6-1.9 m across (arms spread, sculling, floating on the back, a head alone), a boat's 4-13 m,
a jetski's about 2.3 m, a buoy's about 1.8 m and taller than wide, a life ring's 0.8 m. From the
side a swimmer shows head and shoulders above the water, sometimes a waving arm; people stand
on deck and on land.
"""

from __future__ import annotations

import math

import numpy as np

from sim.scene import (
    BGR,
    CLOTHES,
    HAIR,
    HULL,
    LIFE_JACKET,
    RIPPLE,
    SKIN,
    SWIM_CAP,
    WETSUIT,
    Part,
    Upright,
    boat_parts,
    pick_colour,
)

Figure = tuple[list[Part], list[Upright]]
BUOY: tuple[BGR, ...] = (
    (20, 200, 240),
    (30, 40, 200),
    (40, 140, 30),
    (235, 235, 235),
    (20, 110, 245),
)
RING: tuple[BGR, ...] = ((20, 90, 240), (30, 40, 210), (20, 200, 240))


def swimmer(rng: np.random.Generator, life_jacket: bool) -> Figure:
    """A swimmer: treading water with arms sculling (most), floating on the back, or only the
    head showing; a third of those treading wave an arm above the water."""
    skin = pick_colour(rng, SKIN)
    cover = pick_colour(rng, SWIM_CAP) if rng.random() < 0.3 else pick_colour(rng, HAIR)
    suit = pick_colour(rng, WETSUIT) if rng.random() < 0.6 else skin
    torso = pick_colour(rng, LIFE_JACKET) if life_jacket else suit
    shoulders = float(rng.uniform(0.2, 0.25)) + (0.05 if life_jacket else 0.0)
    u = rng.random()
    if u < 0.15 and not life_jacket:
        splash = float(rng.uniform(0.3, 0.45))
        flat = [
            Part("ellipse", 0.0, 0.0, 1.3 * splash, 1.2 * splash, 0.0, RIPPLE, 0.15, 0.0, False),
            Part("ellipse", 0.0, 0.0, splash, 0.9 * splash, 0.0, RIPPLE, 0.3, 0.0),
        ]
        return flat, _head(cover, skin, 0.0)
    if u < 0.4:
        length = float(rng.uniform(1.5, 1.85))
        half = length / 2
        flat = [
            Part("ellipse", 0.0, 0.0, 1.05 * half, 0.4, 0.0, RIPPLE, 0.12, 0.0, False),
            Part("ellipse", -0.5 * half, 0.0, 0.5 * half, 0.17, 0.0, suit, 0.45, 0.2),
            Part("ellipse", 0.2 * half, 0.0, 0.4 * half, shoulders, 0.0, torso, 0.85, 0.3),
            Part("ellipse", 0.2 * half + 0.45 * half + 0.1, 0.0, 0.12, 0.1, 0.0, cover, 0.9, 0.3),
        ]
        span = float(rng.uniform(0.55, 0.8))
        for side in (-1.0, 1.0):
            flat.append(
                Part(
                    "ellipse",
                    0.3 * half,
                    side * (shoulders + span / 2),
                    span / 2,
                    0.05,
                    side * 1.3,
                    skin,
                    0.55,
                    0.1,
                )
            )
        upright = [
            Upright("ellipse", 0.2 * half, 0.0, 0.4 * half, shoulders, 0.0, 0.1, torso, 0.9, 0.3),
            Upright("ellipse", 0.75 * half, 0.0, 0.11, 0.09, 0.0, 0.14, skin, 0.9, 0.2),
        ]
        return flat, upright
    span = float(rng.uniform(0.3, 0.65))  # each arm, sculling on the surface
    flat = [
        Part("ellipse", 0.0, 0.0, 0.6, shoulders + span + 0.15, 0.0, RIPPLE, 0.15, 0.0, False),
        Part("ellipse", -0.15, 0.0, 0.35, shoulders, 0.0, torso, 0.5, 0.3),
    ]
    for side in (-1.0, 1.0):
        flat.append(
            Part(
                "ellipse",
                0.05,
                side * (shoulders + span / 2),
                span / 2,
                0.055,
                side * 0.25,
                skin,
                0.5,
                0.15,
            )
        )
    upright = [
        Upright("ellipse", 0.0, 0.0, 0.13, shoulders, -0.05, 0.14, torso, 0.95, 0.3),
        *_head(cover, skin, 0.1),
    ]
    if rng.random() < 0.33:
        side = 1.0 if rng.random() < 0.5 else -1.0
        upright.append(
            Upright(
                "ellipse",
                0.0,
                side * shoulders,
                0.05,
                0.05,
                0.08,
                float(rng.uniform(0.65, 0.8)),
                skin,
                0.95,
                0.2,
                tilt=side * 0.35,
                swing=0.45,
                phase=float(rng.random()),
            )
        )
    return flat, upright


def _head(cover: BGR, skin: BGR, bottom: float) -> list[Upright]:
    """A head rising from ``bottom`` metres: hair or cap, and the face below it."""
    return [
        Upright("ellipse", 0.0, 0.0, 0.1, 0.09, bottom, bottom + 0.24, cover, 0.97, 0.35),
        Upright("ellipse", 0.03, 0.0, 0.08, 0.07, bottom + 0.02, bottom + 0.16, skin, 0.85, 0.2),
    ]


def standing_person(rng: np.random.Generator, base: float = 0.0) -> list[Upright]:
    """A person standing on a surface ``base`` metres above the object's plane: legs, body,
    head, 1.6-1.85 m tall."""
    tall = float(rng.uniform(1.6, 1.85))
    clothes = pick_colour(rng, CLOTHES)
    legs = pick_colour(rng, CLOTHES)
    width = float(rng.uniform(0.2, 0.25))
    y = float(rng.uniform(-0.3, 0.3))
    return [
        Upright("box", 0.0, y, 0.12, 0.7 * width, base, base + 0.48 * tall, legs, 1.0, 0.2),
        Upright(
            "box", 0.0, y, 0.13, width, base + 0.46 * tall, base + 0.84 * tall, clothes, 1.0, 0.25
        ),
        Upright(
            "ellipse",
            0.0,
            y,
            0.1,
            0.09,
            base + 0.84 * tall,
            base + tall,
            pick_colour(rng, HAIR),
            1.0,
            0.3,
        ),
    ]


def person_on_land(rng: np.random.Generator, flat: list[Part]) -> Figure:
    """A pedestrian: the flat figure seen from above plus the standing body from the side."""
    return flat, standing_person(rng)


def boat(rng: np.random.Generator, moving: bool) -> Figure:
    """A boat 4-13 m long: the flat hull and wake, its side above the water, a cabin or
    console, and one to three people standing on deck."""
    length = float(rng.uniform(4.0, 7.0) if rng.random() < 0.75 else rng.uniform(7.0, 13.0))
    flat = boat_parts(rng, length, moving)
    half, beam = length / 2, 0.19 * length
    hull = flat[-4].bgr
    freeboard = float(rng.uniform(0.5, 0.4 + 0.08 * length))
    cabin = pick_colour(rng, ((220, 220, 220), (70, 70, 75), (150, 150, 150)))
    upright = [
        Upright("box", 0.0, 0.0, 0.95 * half, beam, 0.0, freeboard, hull, 1.0, 0.2),
        Upright(
            "box",
            -0.3 * half,
            0.0,
            0.3 * half,
            0.6 * beam,
            freeboard,
            freeboard + float(rng.uniform(0.8, 1.6)),
            cabin,
            1.0,
            0.25,
        ),
    ]
    for _ in range(int(rng.integers(1, 4))):
        person = standing_person(rng, freeboard - 0.3)
        x = float(rng.uniform(-0.8, 0.3)) * half
        upright += [
            Upright(
                p.shape,
                x,
                p.y * beam,
                p.half_length,
                p.half_width,
                p.bottom,
                p.top,
                p.bgr,
                p.opacity,
                p.shade,
            )
            for p in person
        ]
    return flat, upright


def jetski(rng: np.random.Generator, moving: bool) -> Figure:
    """A jetski 2.8-3.4 m long with a rider sitting or standing on it."""
    length = float(rng.uniform(2.8, 3.4))
    half, beam = length / 2, 0.6
    hull = pick_colour(rng, HULL)
    foam = (235.0, 238.0, 235.0)
    flat: list[Part] = []
    if moving:
        flat.append(
            Part(
                "ellipse", -half - 1.5 * length, 0.0, 1.6 * length, 0.7, 0.0, foam, 0.35, 0.0, False
            )
        )
    flat += [
        Part("ellipse", 0.1 * half, 0.0, half, beam, 0.0, hull, 1.0, 0.2),
        Part("box", -0.2 * half, 0.0, 0.35 * half, 0.22, 0.0, (30, 30, 32), 1.0, 0.1),
    ]
    rider = standing_person(rng, 0.45)
    if rng.random() < 0.6:  # sitting: the legs fold, the body starts lower
        rider = [
            Upright(
                p.shape,
                p.x,
                p.y,
                p.half_length,
                p.half_width,
                p.bottom - 0.5,
                p.top - 0.5,
                p.bgr,
                p.opacity,
                p.shade,
            )
            for p in rider[1:]
        ]
    upright = [
        Upright("box", 0.0, 0.0, 0.9 * half, beam, 0.0, 0.5, hull, 1.0, 0.2),
        *[
            Upright(
                p.shape,
                -0.2 * half,
                0.0,
                p.half_length,
                p.half_width,
                p.bottom,
                p.top,
                p.bgr,
                p.opacity,
                p.shade,
            )
            for p in rider
        ],
    ]
    return flat, upright


def buoy(rng: np.random.Generator) -> Figure:
    """A marker buoy 1.3-2.1 m across, its body up to about a metre high and a top mark above."""
    width = float(rng.uniform(1.3, 2.1))
    colour = pick_colour(rng, BUOY)
    body_top = float(rng.uniform(0.6, 1.1))
    flat = [
        Part("ellipse", 0.0, 0.0, 0.7 * width, 0.7 * width, 0.0, RIPPLE, 0.12, 0.0, False),
        Part("ellipse", 0.0, 0.0, width / 2, width / 2, 0.0, colour, 1.0, 0.35),
    ]
    upright = [
        Upright("ellipse", 0.0, 0.0, width / 2, width / 2, 0.0, body_top, colour, 1.0, 0.3),
        Upright(
            "box", 0.0, 0.0, 0.06, 0.06, body_top, body_top + 0.9 * width, (60, 60, 60), 1.0, 0.1
        ),
        Upright(
            "ellipse",
            0.0,
            0.0,
            0.2,
            0.2,
            body_top + 0.7 * width,
            body_top + 0.9 * width,
            colour,
            1.0,
            0.2,
        ),
    ]
    return flat, upright


def life_ring(rng: np.random.Generator) -> Figure:
    """A life ring 0.75-0.85 m across, red or orange with white bands, floating flat."""
    outer = float(rng.uniform(0.375, 0.425))
    thick = 0.08
    colour = pick_colour(rng, RING)
    white = (235.0, 235.0, 235.0)
    flat = []
    for k in range(12):  # the ring as twelve short segments round its centre line
        a = 2 * math.pi * k / 12
        r = outer - thick
        flat.append(
            Part(
                "ellipse",
                r * math.cos(a),
                r * math.sin(a),
                0.14,
                thick,
                a + math.pi / 2,
                white if k % 3 == 0 else colour,
                1.0,
                0.2,
            )
        )
    upright = [Upright("ellipse", 0.0, 0.0, outer, outer, 0.0, 0.1, colour, 0.9, 0.2)]
    return flat, upright
