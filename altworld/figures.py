"""The figures of the alternative world, drawn in metres on a :class:`~altworld.canvas.Canvas`.

Each kind has a ``draw_<kind>(canvas, look, t)`` function; ``look`` holds the figure's fixed
appearance (drawn once per figure by :func:`new_look`) and ``t`` is the clip time in seconds, for
strokes, steps and wing beats. The figure faces canvas-up (its heading).
"""

from __future__ import annotations

import math

import numpy as np

from altworld.canvas import Canvas

BGR = tuple[float, float, float]

HAIR: tuple[BGR, ...] = (
    (20, 20, 25),
    (30, 45, 70),
    (60, 110, 160),
    (110, 170, 215),
    (150, 150, 150),
    (40, 60, 140),
)
SKIN: tuple[BGR, ...] = (
    (150, 180, 225),
    (110, 150, 200),
    (80, 115, 165),
    (50, 75, 110),
    (170, 195, 235),
)
CAP: tuple[BGR, ...] = (
    (30, 30, 220),
    (20, 200, 240),
    (240, 240, 240),
    (200, 90, 30),
    (25, 25, 25),
    (200, 60, 200),
)
CLOTH: tuple[BGR, ...] = (
    (40, 40, 40),
    (200, 200, 205),
    (150, 60, 20),
    (40, 40, 170),
    (30, 120, 40),
    (60, 160, 200),
    (130, 110, 100),
    (30, 90, 200),
    (110, 40, 110),
    (20, 20, 120),
    (90, 130, 90),
    (160, 150, 70),
)
JACKET: tuple[BGR, ...] = (
    (0, 90, 250),
    (0, 200, 255),
    (30, 40, 210),
    (10, 140, 255),
    (40, 200, 200),
)
#: Sea distractor colours: plastic, wood, weed, buoys, hulls.
PLASTIC: tuple[BGR, ...] = (
    (230, 230, 230),
    (40, 150, 240),
    (200, 120, 30),
    (50, 50, 200),
    (60, 200, 90),
    (20, 210, 240),
)
WOOD: tuple[BGR, ...] = ((40, 70, 110), (60, 95, 130), (30, 50, 70), (90, 120, 150))
WEED: tuple[BGR, ...] = ((30, 60, 60), (20, 45, 40), (40, 80, 90))
BUOY: tuple[BGR, ...] = ((20, 30, 210), (0, 110, 250), (20, 210, 240), (230, 230, 230))
HULL: tuple[BGR, ...] = (
    (235, 235, 235),
    (40, 40, 180),
    (160, 90, 20),
    (30, 170, 240),
    (60, 60, 60),
    (60, 150, 60),
)
FUR: tuple[BGR, ...] = (
    (40, 70, 110),
    (25, 30, 40),
    (200, 205, 210),
    (60, 100, 150),
    (100, 120, 140),
)


def pick(rng: np.random.Generator, palette: tuple[BGR, ...], jitter: float = 18.0) -> BGR:
    """A palette colour with a little random variation."""
    base = np.asarray(palette[int(rng.integers(len(palette)))], np.float64)
    return tuple(np.clip(base + rng.normal(0, jitter, 3), 0, 255).tolist())


def mix(a: BGR, b: BGR, w: float) -> BGR:
    """``a`` blended towards ``b`` by ``w``."""
    return tuple(float(x * (1 - w) + y * w) for x, y in zip(a, b, strict=True))


#: kind -> (extent of its canvas in metres, COCO category or ``None`` for unboxed).
KINDS: dict[str, tuple[float, str | None]] = {
    "swimmer": (2.6, "swimmer"),
    "jacket": (2.6, "swimmer_with_life_jacket"),
    "person": (4.5, "person"),
    "debris": (1.4, "debris"),
    "weed": (2.5, "debris"),
    "foam": (3.0, None),
    "buoy": (1.2, "buoy"),
    "ring": (1.2, "life_saving_appliances"),
    "gull": (1.6, "bird"),
    "boat": (9.0, "boat"),
    "animal": (3.5, "animal"),
}


def new_look(rng: np.random.Generator, kind: str, water: BGR) -> dict:
    """The fixed appearance of a new figure of ``kind`` over water of colour ``water``."""
    look: dict = {"kind": kind, "water": water, "phase": rng.random() * 2 * math.pi}
    if kind in ("swimmer", "jacket", "person"):
        look["head"] = (
            pick(rng, CAP) if kind != "person" and rng.random() < 0.3 else pick(rng, HAIR)
        )
        look["skin"] = pick(rng, SKIN)
        look["top"] = pick(rng, CLOTH, 25)
        look["bottom"] = pick(rng, CLOTH, 25)
        look["build"] = rng.uniform(0.85, 1.15)
        look["jacket"] = pick(rng, JACKET, 10)
        look["tape"] = rng.random() < 0.5
        look["pose"] = rng.choice(
            ["upright", "float", "stroke"] if kind != "person" else ["stand", "walk", "sit", "lie"]
        )
        look["depth"] = rng.uniform(0.25, 0.75)  # how much of the body the water hides
        look["arms"] = rng.uniform(-0.6, 0.6, 2)
    elif kind == "debris":
        look["shape"] = rng.choice(["plank", "box", "bottle", "sheet"])
        look["colour"] = pick(rng, WOOD) if look["shape"] == "plank" else pick(rng, PLASTIC)
        look["size"] = rng.uniform(0.15, 0.6)
    elif kind == "weed":
        look["colour"] = pick(rng, WEED, 10)
        look["points"] = _blob(rng, rng.uniform(0.3, 1.1), 11)
    elif kind == "foam":
        look["points"] = [
            _blob(rng, rng.uniform(0.2, 1.3), 9) for _ in range(int(rng.integers(1, 4)))
        ]
        look["offsets"] = rng.uniform(-0.6, 0.6, (3, 2))
    elif kind in ("buoy", "ring"):
        look["colour"] = pick(rng, BUOY, 10)
        look["radius"] = rng.uniform(0.2, 0.35) if kind == "buoy" else rng.uniform(0.3, 0.4)
    elif kind == "gull":
        look["flying"] = rng.random() < 0.5
        look["grey"] = rng.uniform(110, 190)
    elif kind == "boat":
        look["hull"] = pick(rng, HULL, 12)
        look["length"] = rng.uniform(2.5, 7.0)
        look["kayak"] = rng.random() < 0.4
        look["deck"] = pick(rng, HULL, 12)
    elif kind == "animal":
        look["fur"] = pick(rng, FUR, 15)
        look["length"] = rng.uniform(0.7, 2.2)
        look["spots"] = rng.random() < 0.25
    return look


def _blob(rng: np.random.Generator, radius: float, n: int) -> list[tuple[float, float]]:
    angles = np.sort(rng.uniform(0, 2 * math.pi, n))
    radii = radius * rng.uniform(0.5, 1.2, n)
    return [
        (float(r * math.cos(a)), float(r * math.sin(a))) for r, a in zip(radii, angles, strict=True)
    ]


def draw(
    canvas: Canvas,
    look: dict,
    t: float,
    rng: np.random.Generator,
    lean: float = 0.0,
    sun: float = 0.0,
) -> None:
    """Draw ``look`` at clip time ``t``; ``lean`` (metres) stretches upright figures away from
    the camera (canvas down), ``sun`` is the sun's azimuth in the figure's frame (radians) for
    shadows on land."""
    kind = look["kind"]
    if kind in ("swimmer", "jacket"):
        _swimmer(canvas, look, t, rng)
    elif kind == "person":
        _person(canvas, look, t, lean, sun)
    elif kind == "animal":
        _animal(canvas, look, t, sun)
    else:
        _OBJECTS[kind](canvas, look, t, rng)


def _swimmer(c: Canvas, look: dict, t: float, rng: np.random.Generator) -> None:
    water, b, depth = look["water"], look["build"], look["depth"]
    phase = look["phase"] + t * 2.2
    sunk = 1.0 - depth

    def under(colour: BGR, extra: float = 0.0) -> BGR:
        return mix(colour, water, min(0.9, depth + extra))

    c.ellipse(
        0,
        0.05,
        0.34 * b,
        0.3 * b,
        0,
        mix(water, (235, 235, 235), 0.35),
        0.25 * sunk + 0.1,
        body=False,
    )
    if look["pose"] == "float":
        c.limb(-0.1, -0.35, -0.15, -1.0, 0.13 * b, under(look["bottom"], 0.2), 0.55, body=False)
        c.limb(0.1, -0.35, 0.15, -1.0, 0.13 * b, under(look["bottom"], 0.2), 0.55, body=False)
        c.ellipse(0, -0.1, 0.2 * b, 0.32 * b, 0, under(look["top"]), 0.75)
        for side in (-1, 1):
            c.limb(
                0.2 * side,
                0.05,
                0.55 * side,
                -0.1 + 0.2 * look["arms"][0],
                0.09,
                under(look["skin"]),
                0.7,
            )
        c.ellipse(0, 0.27, 0.09 * b, 0.11 * b, 0, look["skin"], 1.0)
        c.ellipse(0, 0.33, 0.1 * b, 0.07 * b, 0, look["head"], 1.0)
    else:
        c.limb(-0.08, -0.3, -0.1, -0.9, 0.12 * b, under(look["bottom"], 0.3), 0.35, body=False)
        c.limb(0.08, -0.3, 0.1, -0.9, 0.12 * b, under(look["bottom"], 0.3), 0.35, body=False)
        c.ellipse(0, -0.02, 0.23 * b, 0.14 * b, 0, under(look["top"]), 0.8)
        for i, side in enumerate((-1, 1)):
            if look["pose"] == "stroke":
                swing = math.sin(phase + i * math.pi)
                hand = (0.3 * side + 0.2 * side * swing, 0.35 * swing + 0.1)
                c.limb(
                    0.2 * side,
                    0.0,
                    hand[0],
                    hand[1],
                    0.09,
                    under(look["skin"], -0.2 if swing > 0 else 0.2),
                    0.8,
                    body=swing > 0,  # an arm in the air belongs to the box, one under water not
                )
                if swing > 0.6:
                    c.speckle(rng, hand[0], hand[1], 0.15, 7, 0.025, (245, 245, 245), 0.8)
            else:
                a = look["arms"][i]
                skin = under(look["skin"])
                c.limb(0.2 * side, 0.0, 0.45 * side, 0.25 * a, 0.09, skin, 0.65, body=False)
        c.ellipse(0, 0.12, 0.095 * b, 0.115 * b, 0, look["head"], 1.0)
        c.ellipse(
            0, 0.17, 0.07 * b, 0.05 * b, 0, look["skin"], 0.35 if look["head"] in CAP else 0.0
        )
    if look["kind"] == "jacket":
        collar = look["jacket"]
        c.ellipse(0, 0.0, 0.25 * b, 0.16 * b, 0, collar, 0.95)
        c.ellipse(0, 0.11, 0.1 * b, 0.1 * b, 0, look["head"], 1.0)
        if look["tape"]:
            c.limb(-0.18, -0.04, 0.18, -0.04, 0.025, (250, 250, 250), 0.9)


def _person(c: Canvas, look: dict, t: float, lean: float, sun: float) -> None:
    b, pose = look["build"], look["pose"]
    height = 1.7 * b if pose in ("stand", "walk") else (0.9 * b if pose == "sit" else 0.3)
    shadow = min(3.0, height * 1.2)
    sx, sy = math.sin(sun) * shadow, math.cos(sun) * shadow
    if pose == "lie":
        c.limb(0, 0, sx * 0.15, sy * 0.15 - 0.2, 0.5, (0, 0, 0), 0.35, body=False)
        c.limb(-0.1, -0.2, -0.2, -0.95, 0.13 * b, look["bottom"])
        c.limb(0.1, -0.2, 0.2, -0.95, 0.13 * b, look["bottom"])
        c.ellipse(0, 0.15, 0.22 * b, 0.36 * b, 0, look["top"])
        c.limb(-0.2, 0.35, -0.45, 0.1 + look["arms"][0] * 0.3, 0.09, look["top"])
        c.limb(0.2, 0.35, 0.45, 0.1 + look["arms"][1] * 0.3, 0.09, look["top"])
        c.ellipse(0, 0.62, 0.1 * b, 0.12 * b, 0, look["skin"])
        c.ellipse(0, 0.66, 0.1 * b, 0.08 * b, 0, look["head"])
        return
    c.limb(0, 0, sx, sy, 0.4 * b, (0, 0, 0), 0.45, body=False)
    # the figure's height seen from the side, pointing away from the camera (canvas down)
    top = -lean * height / 1.7
    step = math.sin(look["phase"] + t * 5.5) * 0.25 if pose == "walk" else 0.0
    if pose == "sit":
        c.ellipse(0, top * 0.3 + 0.1, 0.22 * b, 0.2 * b, 0, look["bottom"])
    else:
        c.limb(-0.08 + step * 0.3, 0.0 + step, -0.08, top * 0.45, 0.12 * b, look["bottom"])
        c.limb(0.08 - step * 0.3, 0.0 - step, 0.08, top * 0.45, 0.12 * b, look["bottom"])
    c.limb(0, top * 0.5, 0, top * 0.8, 0.36 * b, look["top"])
    c.limb(-0.2, top * 0.78, -0.22 - step * 0.2, top * 0.5 - step, 0.08, look["top"])
    c.limb(0.2, top * 0.78, 0.22 + step * 0.2, top * 0.5 + step, 0.08, look["top"])
    c.ellipse(0, top * 0.7, 0.23 * b, 0.13 * b, 0, look["top"])
    c.ellipse(0, top * 0.95 + 0.02, 0.1 * b, 0.11 * b, 0, look["head"])


def _animal(c: Canvas, look: dict, t: float, sun: float) -> None:
    n = look["length"]
    fur = look["fur"]
    c.limb(0, 0, math.sin(sun) * n, math.cos(sun) * n, n * 0.45, (0, 0, 0), 0.4, body=False)
    nod = 0.1 * n * math.sin(look["phase"] + t * 0.8)
    c.ellipse(0, 0, n * 0.22, n * 0.5, 0, fur)
    c.limb(0, n * 0.4, 0, n * 0.62 + nod, n * 0.15, mix(fur, (0, 0, 0), 0.2))
    c.limb(0, -n * 0.45, 0.05 * n, -n * 0.62, n * 0.05, fur)
    if look["spots"]:
        c.ellipse(0.05 * n, 0.1 * n, n * 0.1, n * 0.13, 20, (235, 235, 235), 0.9)


def _debris(c: Canvas, look: dict, t: float, rng: np.random.Generator) -> None:
    s, col = look["size"], look["colour"]
    shape = look["shape"]
    if shape == "plank":
        c.limb(0, -s, 0, s, 0.09 + 0.1 * s, col, 0.95)
    elif shape == "box":
        c.polygon([(-s / 2, -s / 3), (s / 2, -s / 3), (s / 2, s / 3), (-s / 2, s / 3)], col, 0.9)
    elif shape == "bottle":
        c.limb(0, -s * 0.4, 0, s * 0.4, 0.08, col, 0.85)
    else:
        c.ellipse(0, 0, s, s * 0.6, 30, mix(col, look["water"], 0.45), 0.7)


def _weed(c: Canvas, look: dict, t: float, rng: np.random.Generator) -> None:
    c.polygon(look["points"], look["colour"], 0.85)


def _foam(c: Canvas, look: dict, t: float, rng: np.random.Generator) -> None:
    fade = 0.5 + 0.35 * math.sin(look["phase"] + t * 0.7)
    for pts, (dx, dy) in zip(look["points"], look["offsets"], strict=False):
        c.polygon([(x + dx, y + dy) for x, y in pts], (240, 240, 240), 0.2 * fade, body=False)
        c.speckle(rng, dx, dy, 0.8, 25, 0.04, (245, 245, 245), 0.8 * fade)


def _buoy(c: Canvas, look: dict, t: float, rng: np.random.Generator) -> None:
    r = look["radius"]
    c.ellipse(0.05, -0.05, r * 1.3, r * 1.2, 0, mix(look["water"], (0, 0, 0), 0.3), 0.5, body=False)
    c.ellipse(0, 0, r, r, 0, look["colour"])
    c.ellipse(
        -r * 0.3, r * 0.3, r * 0.3, r * 0.25, 0, mix(look["colour"], (255, 255, 255), 0.6), 0.9
    )


def _ring(c: Canvas, look: dict, t: float, rng: np.random.Generator) -> None:
    r = look["radius"]
    c.ellipse(0, 0, r, r, 0, look["colour"])
    for k in range(4):
        a = k * math.pi / 2 + 0.4
        c.ellipse(
            r * 0.8 * math.cos(a), r * 0.8 * math.sin(a), r * 0.22, r * 0.22, 0, (245, 245, 245)
        )
    c.ellipse(0, 0, r * 0.55, r * 0.55, 0, look["water"])


def _gull(c: Canvas, look: dict, t: float, rng: np.random.Generator) -> None:
    grey = look["grey"]
    if look["flying"]:
        beat = 0.35 * math.sin(look["phase"] + t * 14.0)
        for side in (-1, 1):
            c.limb(0, 0, 0.35 * side, 0.05 + beat, 0.1, (grey, grey, grey))
            c.limb(0.35 * side, 0.05 + beat, 0.65 * side, -0.1 + beat, 0.07, (30, 30, 30))
        c.ellipse(0, 0, 0.06, 0.2, 0, (245, 245, 245))
    else:
        c.ellipse(0, 0, 0.1, 0.2, 0, (245, 245, 245))
        c.ellipse(0, -0.03, 0.08, 0.14, 0, (grey, grey, grey))
        c.ellipse(0, -0.19, 0.04, 0.05, 0, (30, 30, 30))


def _boat(c: Canvas, look: dict, t: float, rng: np.random.Generator) -> None:
    n = look["length"]
    w = n * (0.12 if look["kayak"] else 0.35)
    c.polygon(
        [(-w * 0.9, -n * 0.45), (-w, n * 0.5), (w, n * 0.5), (w * 0.9, -n * 0.45)],
        (245, 245, 245),
        0.4,
        body=False,
    )
    c.polygon(
        [(0, n * 0.5), (w, n * 0.15), (w * 0.85, -n * 0.5), (-w * 0.85, -n * 0.5), (-w, n * 0.15)],
        look["hull"],
    )
    if not look["kayak"]:
        c.polygon(
            [(-w * 0.6, -n * 0.1), (w * 0.6, -n * 0.1), (w * 0.6, -n * 0.4), (-w * 0.6, -n * 0.4)],
            look["deck"],
        )
    else:
        c.ellipse(0, 0, w * 0.5, n * 0.08, 0, (30, 30, 30))


_OBJECTS = {
    "debris": _debris,
    "weed": _weed,
    "foam": _foam,
    "buoy": _buoy,
    "ring": _ring,
    "gull": _gull,
    "boat": _boat,
}
