"""Worlds of figures with height (``Scenario.figures == "upright"``), for oblique views.

The maritime world holds what a real maritime search meets (the SeaDronesSee classes): swimmers
(:func:`sim.upright_figures.swimmer`), boats with people on deck, jetskis with riders, anchored
buoys and drifting life rings, beside the flat scene's birds, debris and sun glints. Motion
follows :mod:`sim.scene`: swimmers, life rings and debris drift with the current, boats and
jetskis loop across the area, buoys stay on their moorings. The urban world is the flat one
with its pedestrians standing.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from sim import upright_figures as figures
from sim.scene import (
    Scenario,
    SceneObject,
    World,
    add_birds_debris_glints,
    build_world,
    loop_start,
    uniform_in,
)


def build_upright_world(scenario: Scenario) -> World:
    """Place every object of ``scenario`` with upright parts (deterministic from its seed)."""
    if scenario.kind == "maritime":
        return World(scenario, _maritime_objects(scenario))
    flat = build_world(scenario)
    rng = np.random.default_rng([scenario.seed, 4])
    objects = [
        dataclasses.replace(o, upright=figures.standing_person(rng))
        if o.category == "person"
        else o
        for o in flat.objects
    ]
    return World(scenario, objects, flat.layout)


def _maritime_objects(sc: Scenario) -> list[SceneObject]:
    rng = np.random.default_rng([sc.seed, 5])
    drift_dir = math.radians(sc.wind_from_deg + 180.0 + rng.normal(0, 25))
    objects: list[SceneObject] = []

    def drift() -> tuple[float, float]:
        speed = rng.uniform(*sc.drift_m_s)
        d = drift_dir + rng.normal(0, 0.3)
        return speed * math.cos(d), speed * math.sin(d)

    def add(
        category: str,
        figure: figures.Figure,
        origin: tuple[float, float],
        heading: float,
        **motion: object,
    ) -> None:
        flat, upright = figure
        objects.append(
            SceneObject(
                len(objects) + 1, category, origin, heading, flat, upright=upright, **motion
            )
        )

    bob = 0.12 + 0.1 * sc.sea_state
    for k in range(sc.n_swimmers + sc.n_life_jacket):
        jacket = k >= sc.n_swimmers
        add(
            "swimmer_with_life_jacket" if jacket else "swimmer",
            figures.swimmer(rng, jacket),
            uniform_in(rng, sc.area_ne),
            float(rng.uniform(0, 2 * math.pi)),
            velocity_ne=drift(),
            wander_m=float(rng.uniform(0.2, 1.0)),
            wander_period_s=float(rng.uniform(30, 90)),
            turn_rate=float(rng.normal(0, 0.05)),
            period_s=float(rng.uniform(1.5, 3.0)),
            bob_depth=float(min(0.6, bob * rng.uniform(0.3, 1.0))),
            bob_period_s=float(rng.uniform(3.0, 7.0)),
            phase=float(rng.random()),
        )
    n0, e0, n1, e1 = sc.area_ne
    diag = math.hypot(n1 - n0, e1 - e0)
    for category, count, speeds in (
        ("boat", sc.n_boats, (1.0, 8.0)),
        ("jetski", sc.n_jetskis, (3.0, 14.0)),
    ):
        for _ in range(count):
            heading = float(rng.uniform(0, 2 * math.pi))
            moving = rng.random() < 0.7
            speed = float(rng.uniform(*speeds)) if moving else 0.0
            figure = (
                figures.boat(rng, moving) if category == "boat" else figures.jetski(rng, moving)
            )
            if moving:
                add(
                    category,
                    figure,
                    loop_start(rng, sc.area_ne, heading, diag),
                    heading,
                    velocity_ne=(speed * math.cos(heading), speed * math.sin(heading)),
                    loop_m=diag + 200.0,
                    phase=float(rng.random()),
                )
            else:
                add(
                    category,
                    figure,
                    uniform_in(rng, sc.area_ne),
                    heading,
                    turn_rate=float(rng.normal(0, 0.01)),
                )
    for _ in range(sc.n_buoys):
        add(
            "buoy",
            figures.buoy(rng),
            uniform_in(rng, sc.buoy_area_ne or sc.area_ne),
            0.0,
            wander_m=0.3,
            wander_period_s=float(rng.uniform(20, 40)),
            phase=float(rng.random()),
        )
    for _ in range(sc.n_life_rings):
        add(
            "life_saving_appliances",
            figures.life_ring(rng),
            uniform_in(rng, sc.area_ne),
            float(rng.uniform(0, 2 * math.pi)),
            velocity_ne=drift(),
            turn_rate=float(rng.normal(0, 0.05)),
            bob_depth=float(min(0.4, 0.5 * bob)),
            bob_period_s=float(rng.uniform(3.0, 7.0)),
            phase=float(rng.random()),
        )
    add_birds_debris_glints(objects, rng, sc, diag, bob, drift)
    return objects
