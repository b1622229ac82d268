"""Training material drawn on request only: people floating on their back with arms and legs
spread (the starfish pose), round mooring buoys, and the presets that show them."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from sim.flight import Flight
from sim.render import SceneRenderer
from sim.scenarios import PRESETS, preset
from sim.scene import Scenario, _maritime_objects, mooring_buoy_parts, swimmer_parts
from sim.sprites import outline_points

PEOPLE = ("swimmer", "swimmer_with_life_jacket")


def boxed_extent(parts: list) -> tuple[float, float]:
    """Length along the body axis and width across it of the parts that make up the box."""
    points = np.concatenate([outline_points(p.placed()) for p in parts if p.in_box])
    return float(np.ptp(points[:, 0])), float(np.ptp(points[:, 1]))


@pytest.mark.parametrize("life_jacket", [False, True])
def test_a_starfish_is_boxed_across_its_spread_limbs(life_jacket: bool) -> None:
    """Spread arms and legs, always at the surface, widen the box to most of the body's
    length."""
    for seed in range(20):
        length, width = boxed_extent(
            swimmer_parts(np.random.default_rng(seed), 1.7, "starfish", life_jacket)
        )
        assert 1.4 < length < 2.0, (seed, length)
        assert width > 0.6 * length, (seed, length, width)


def test_a_starfish_scales_with_its_length() -> None:
    small = boxed_extent(swimmer_parts(np.random.default_rng(3), 1.3, "starfish", False))
    large = boxed_extent(swimmer_parts(np.random.default_rng(3), 1.8, "starfish", False))
    assert large[0] / small[0] == pytest.approx(1.8 / 1.3, rel=1e-6)
    assert large[1] / small[1] == pytest.approx(1.8 / 1.3, rel=1e-6)


def test_starfish_change_only_the_people_on_their_back() -> None:
    """Every other object, and every person's place and motion, stays as the world without
    them draws it, so presets that leave the share at 0 render as before."""
    plain = Scenario(kind="maritime", seed=41, n_swimmers=40, n_life_jacket=20)
    spread = replace(plain, starfish_fraction=1.0)
    before, after = _maritime_objects(plain), _maritime_objects(spread)
    assert len(before) == len(after)
    changed = 0
    for old, new in zip(before, after, strict=True):
        assert replace(old, parts=[]) == replace(new, parts=[])
        if old.parts != new.parts:
            changed += 1
            assert old.category in PEOPLE
            # the plain float on the back is what turned into a starfish
            assert len(new.parts) == 8 and len(old.parts) == 7
    assert changed >= 10
    assert [o.parts for o in before] == [o.parts for o in _maritime_objects(plain)]


@pytest.mark.parametrize("share", [-0.1, 1.5, math.nan])
def test_a_starfish_share_outside_0_1_is_refused(share: float) -> None:
    with pytest.raises(ValueError, match="starfish_fraction"):
        Scenario(kind="maritime", starfish_fraction=share)


def test_the_floats_preset_shows_people_on_their_back_spread_out() -> None:
    chosen = preset("maritime_floats_train")
    others = {name: make().scenario.seed for name, make in PRESETS.items()}
    assert list(others.values()).count(chosen.scenario.seed) == 1
    people = [o for o in _maritime_objects(chosen.scenario) if o.category in PEOPLE]
    starfish = [o for o in people if len(o.parts) == 8]
    assert len(starfish) >= 0.3 * len(people), (len(starfish), len(people))
    flight = Flight(chosen.mission, seed=chosen.scenario.seed)
    intr = chosen.mission.camera.intrinsics().scaled(960, 540)
    renderer = SceneRenderer(chosen.scenario, intr)
    t = 30.0
    frame, annotations = renderer.render(t, flight.state_at(t).camera_pose())
    assert frame.shape == (540, 960, 3)
    assert sum(a.category in PEOPLE for a in annotations) >= 3


def test_mooring_buoys_follow_every_other_object_and_change_nothing_else() -> None:
    plain = Scenario(kind="maritime", seed=43)
    moored = replace(plain, n_mooring_buoys=9)
    before, after = _maritime_objects(plain), _maritime_objects(moored)
    assert after[: len(before)] == before
    buoys = after[len(before) :]
    assert [b.category for b in buoys] == ["buoy"] * 9
    assert [b.track_id for b in buoys] == list(range(len(before) + 1, len(after) + 1))
    for buoy in buoys:
        assert buoy.velocity_ne == (0.0, 0.0)  # moored: it swings, it does not drift off
        n, e = buoy.origin_ne
        n0, e0, n1, e1 = plain.area_ne
        assert n0 <= n <= n1 and e0 <= e <= e1


def test_a_mooring_buoy_is_boxed_round_at_its_size() -> None:
    for seed in range(10):
        parts = mooring_buoy_parts(np.random.default_rng(seed), 0.8)
        length, width = boxed_extent(parts)
        assert length == pytest.approx(0.8, rel=0.02) and width == pytest.approx(0.8, rel=0.02)
        assert not parts[0].in_box  # the ring of disturbed water is no part of the buoy


def test_a_negative_buoy_count_is_refused() -> None:
    with pytest.raises(ValueError, match="n_mooring_buoys"):
        Scenario(kind="maritime", n_mooring_buoys=-1)


def test_the_buoys_preset_shows_buoys_beside_people() -> None:
    chosen = preset("maritime_buoys_train")
    seeds = [make().scenario.seed for make in PRESETS.values()]
    assert seeds.count(chosen.scenario.seed) == 1
    flight = Flight(chosen.mission, seed=chosen.scenario.seed)
    intr = chosen.mission.camera.intrinsics().scaled(960, 540)
    renderer = SceneRenderer(chosen.scenario, intr)
    seen = [a.category for a in renderer.render(30.0, flight.state_at(30.0).camera_pose())[1]]
    assert seen.count("buoy") >= 2 and sum(c in PEOPLE for c in seen) >= 2, seen


def test_the_high_buoys_preset_shows_the_same_sea_from_higher_up() -> None:
    """From 150 m instead of 80 the buoys are about half as large in the image (80 / 150)."""
    sides = {}
    for name in ("maritime_buoys_train", "maritime_buoys_high_train"):
        chosen = preset(name)
        flight = Flight(chosen.mission, seed=chosen.scenario.seed)
        intr = chosen.mission.camera.intrinsics().scaled(960, 540)
        renderer = SceneRenderer(chosen.scenario, intr)
        seen = renderer.render(30.0, flight.state_at(30.0).camera_pose())[1]
        buoys = [a.bbox_xyxy for a in seen if a.category == "buoy"]
        assert len(buoys) >= 2, name
        sides[name] = np.median([max(x1 - x0, y1 - y0) for x0, y0, x1, y1 in buoys])
    seeds = [make().scenario.seed for make in PRESETS.values()]
    assert seeds.count(preset("maritime_buoys_high_train").scenario.seed) == 1
    ratio = sides["maritime_buoys_high_train"] / sides["maritime_buoys_train"]
    assert 0.4 < ratio < 0.7, sides
