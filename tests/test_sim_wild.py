"""Wild land worlds: every biome renders its own ground, people are targets, animals are not."""

from __future__ import annotations

import math

import numpy as np
import pytest

from sarmission.geo.camera import CameraIntrinsics, CameraPose
from sarmission.geo.frames import rotation_ned_from_camera
from sim.render import SceneRenderer
from sim.scenarios import PRESETS, preset
from sim.scene import Scenario
from sim.wild import BIOMES, WildGround, build_wild_world, trail_points

W, H = 640, 360
NADIR = rotation_ned_from_camera((0.0, 0.0, 0.0), (0.0, -math.pi / 2, 0.0), "vehicle")
INTR = CameraIntrinsics.from_hfov(W, H, 70.0)


def _pose(north: float = 30.0, east: float = 0.0, altitude: float = 40.0) -> CameraPose:
    return CameraPose(np.array([north, east, -altitude]), NADIR)


def _wild(biome: str, seed: int = 5, people: int = 40, animals: int = 20) -> Scenario:
    return Scenario(
        kind="wild",
        seed=seed,
        area_ne=(10.0, -30.0, 50.0, 30.0),
        biome=biome,
        n_pedestrians=people,
        n_animals=animals,
    )


@pytest.fixture(scope="module")
def frames() -> dict[str, tuple[np.ndarray, list]]:
    return {b: SceneRenderer(_wild(b), INTR).render(2.0, _pose()) for b in BIOMES}


def test_every_biome_has_its_own_look(frames) -> None:
    means = {b: f.reshape(-1, 3).mean(axis=0) for b, (f, _) in frames.items()}
    # snow is the brightest ground, forest the darkest
    assert max(means, key=lambda b: means[b].sum()) == "snow"
    assert min(means, key=lambda b: means[b].sum()) == "forest"
    for a in BIOMES:
        for b in BIOMES:
            if a < b:
                assert np.abs(means[a] - means[b]).max() > 8.0, (a, b)
    for frame, _ in frames.values():
        assert frame.shape == (H, W, 3) and frame.dtype == np.uint8
        assert frame.reshape(-1, 3).std(axis=0).min() > 3.0  # textured, not flat


def test_people_are_targets_and_animals_are_not(frames) -> None:
    for biome, (_, anns) in frames.items():
        people = [a for a in anns if a.category == "person"]
        animals = [a for a in anns if a.category == "animal"]
        assert people and animals, biome
        assert all(a.is_target for a in people) and not any(a.is_target for a in animals)
        at_40m = 40.0 / INTR.fx  # metres per pixel at the image centre
        for a in people:
            x0, y0, x1, y1 = a.bbox_xyxy
            assert max(x1 - x0, y1 - y0) * at_40m < 2.5  # no box larger than a lying person


def test_people_walk_stand_sit_and_lie() -> None:
    world = build_wild_world(_wild("meadow", people=200, animals=0))
    people = [o for o in world.objects if o.category == "person"]
    moving = [o for o in people if np.hypot(*o.velocity_ne) > 0]
    assert 0.25 < len(moving) / len(people) < 0.55  # 40 % walk
    spans = [
        max(p.x + p.a for p in o.parts if p.in_box) - min(p.x - p.a for p in o.parts if p.in_box)
        for o in people
    ]
    assert max(spans) > 1.4  # someone lies full length
    assert min(spans) < 0.4  # someone stands, seen from above
    assert all(o.category == "person" for o in world.objects)


def test_the_same_seed_paints_the_same_ground_and_another_does_not() -> None:
    a = WildGround(build_wild_world(_wild("rock", seed=1))).texture
    b = WildGround(build_wild_world(_wild("rock", seed=1))).texture
    c = WildGround(build_wild_world(_wild("rock", seed=2))).texture
    assert np.array_equal(a, b)
    assert a.shape == c.shape and np.mean(np.abs(a.astype(int) - c.astype(int))) > 5.0


def test_the_trail_crosses_the_area() -> None:
    sc = _wild("forest")
    trail = trail_points(sc)
    n0, e0, n1, e1 = sc.area_ne
    assert trail[:, 0].min() < n0 and trail[:, 0].max() > n1
    inside = (trail[:, 0] > n0) & (trail[:, 0] < n1)
    assert ((trail[inside, 1] > e0 - 80) & (trail[inside, 1] < e1 + 80)).all()


def test_bad_wild_settings_are_refused() -> None:
    with pytest.raises(ValueError, match="unknown biome 'jungle'; known: meadow"):
        build_wild_world(_wild("jungle"))
    with pytest.raises(ValueError, match="flat figures only"):
        Scenario(kind="wild", figures="upright")
    with pytest.raises(ValueError, match="'wild'"):
        Scenario(kind="desert")


def test_wild_presets_cover_every_biome() -> None:
    wild = [preset(name) for name in PRESETS if name.startswith("wild_")]
    assert sorted(p.scenario.biome for p in wild) == sorted(BIOMES)
    assert all(p.scenario.kind == "wild" and p.scenario.n_pedestrians >= 1 for p in wild)
