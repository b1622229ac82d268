"""Scene renderer: determinism, exact boxes and ground positions, motion, size bands."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from sarmission.data.coco_video import read_coco_video
from sarmission.geo.camera import CameraIntrinsics, CameraPose, project_points
from sarmission.geo.frames import rotation_ned_from_camera
from sim.flight import Flight
from sim.generate import generate_sequence
from sim.render import SceneRenderer
from sim.scenarios import maritime_test
from sim.scene import Part, Scenario, SceneObject, World

W, H = 640, 360
NADIR = rotation_ned_from_camera((0.0, 0.0, 0.0), (0.0, -math.pi / 2, 0.0), "vehicle")


def _pose(north: float = 30.0, east: float = 0.0, altitude: float = 40.0) -> CameraPose:
    return CameraPose(np.array([north, east, -altitude]), NADIR)


def _maritime(seed: int = 7) -> Scenario:
    return Scenario(
        kind="maritime",
        seed=seed,
        area_ne=(10.0, -30.0, 50.0, 30.0),
        sea_state=2,
        n_swimmers=10,
        n_life_jacket=5,
        n_boats=1,
        n_birds=1,
        n_debris=3,
        n_glints=3,
        floating_fraction=0.3,
    )


@pytest.fixture(scope="module")
def intr() -> CameraIntrinsics:
    return CameraIntrinsics.from_hfov(W, H, 70.0)


@pytest.fixture(scope="module")
def renderer(intr: CameraIntrinsics) -> SceneRenderer:
    return SceneRenderer(_maritime(), intr, home=(54.17, 7.89, 0.0))


def test_same_seed_same_frame_and_gt(renderer: SceneRenderer, intr: CameraIntrinsics) -> None:
    a, ann_a = renderer.render(1.5, _pose())
    b, ann_b = SceneRenderer(_maritime(), intr, home=(54.17, 7.89, 0.0)).render(1.5, _pose())
    assert a.shape == (H, W, 3) and a.dtype == np.uint8
    assert np.array_equal(a, b)
    assert ann_a == ann_b and len(ann_a) > 5


def test_different_seed_differs(renderer: SceneRenderer, intr: CameraIntrinsics) -> None:
    a, ann_a = renderer.render(1.5, _pose())
    b, ann_b = SceneRenderer(_maritime(seed=8), intr).render(1.5, _pose())
    assert np.mean(np.abs(a.astype(int) - b.astype(int))) > 3.0
    assert [x.bbox_xyxy for x in ann_a] != [x.bbox_xyxy for x in ann_b]


def test_boxes_contain_the_targets(renderer: SceneRenderer, intr: CameraIntrinsics) -> None:
    frame, anns = renderer.render(2.0, _pose())
    lab = frame.astype(np.float64)
    targets = [
        a
        for a in anns
        if a.is_target
        and a.visibility > 0.6
        and a.bbox_xyxy[2] - a.bbox_xyxy[0] >= 3
        and a.bbox_xyxy[3] - a.bbox_xyxy[1] >= 3
    ]
    assert len(targets) >= 5
    distances = []
    for a in targets:
        x0, y0, x1, y1 = (int(round(v)) for v in a.bbox_xyxy)
        inside = lab[y0:y1, x0:x1].reshape(-1, 3)
        around = np.zeros(frame.shape[:2], bool)
        around[max(0, y0 - 10) : y1 + 10, max(0, x0 - 10) : x1 + 10] = True
        around[max(0, y0 - 3) : y1 + 3, max(0, x0 - 3) : x1 + 3] = False
        sea = lab[around]
        centre = np.median(sea, axis=0)
        spread = np.percentile(np.linalg.norm(sea - centre, axis=1), 95) + 1.0
        distances.append(np.max(np.linalg.norm(inside - centre, axis=1)) / spread)
    # Colour: most boxes hold pixels well outside the spread of the sea around them (a dark
    # swimmer awash in foam may not).
    assert np.median(distances) > 2.0 and np.mean(np.array(distances) > 1.5) >= 0.7, distances
    # Exactness: removing one target changes pixels only in its box (strong changes; its faint
    # splash ring reaches beyond), and changes much inside it.
    for a in targets[:4]:
        world = renderer.world
        without = World(world.scenario, [o for o in world.objects if o.track_id != a.track_id])
        other, _ = SceneRenderer(world.scenario, intr, world=without).render(2.0, _pose())
        change = np.abs(frame.astype(int) - other.astype(int)).max(axis=2)
        changed = change > 30
        rows, cols = np.nonzero(changed)
        assert rows.size > 0
        x0, y0, x1, y1 = a.bbox_xyxy
        margin = 1.5  # anti-aliasing and optical blur
        assert cols.min() + 0.5 >= x0 - margin and cols.max() + 0.5 <= x1 + margin
        assert rows.min() + 0.5 >= y0 - margin and rows.max() + 0.5 <= y1 + margin
        xi0, yi0, xi1, yi1 = (int(round(v)) for v in a.bbox_xyxy)
        assert (change[yi0:yi1, xi0:xi1] > 0).mean() > 0.5


def _single(part: Part, height_m: float = 0.0) -> World:
    sc = Scenario(
        kind="maritime",
        seed=1,
        area_ne=(0.0, -10.0, 10.0, 10.0),
        n_swimmers=0,
        n_life_jacket=0,
        n_boats=0,
        n_birds=0,
        n_debris=0,
        n_glints=0,
    )
    obj = SceneObject(1, "swimmer", (30.0, 0.0), 0.0, [part], height_m=height_m)
    return World(sc, [obj])


@pytest.mark.parametrize("altitude", [40.0, 90.0])
def test_box_matches_analytic_size(intr: CameraIntrinsics, altitude: float) -> None:
    world = _single(Part("ellipse", 0, 0, 0.3, 0.2, 0, (0, 100, 250)))
    renderer = SceneRenderer(world.scenario, intr, world=world)
    _, anns = renderer.render(0.0, _pose(30.0, 0.0, altitude))
    (ann,) = anns
    x0, y0, x1, y1 = ann.bbox_xyxy
    # Heading 0: local x (0.6 m) runs north = image up, local y (0.4 m) east = image right.
    assert x1 - x0 == pytest.approx(0.4 * intr.fx / altitude, rel=0.1)
    assert y1 - y0 == pytest.approx(0.6 * intr.fy / altitude, rel=0.1)


def test_ground_positions_project_into_boxes(
    renderer: SceneRenderer, intr: CameraIntrinsics
) -> None:
    pose = CameraPose(
        np.array([28.0, 3.0, -40.0]),
        rotation_ned_from_camera((0.05, -0.08, 0.4), (0.0, -1.4, 0.0), "vehicle"),
    )
    _, anns = renderer.render(3.0, pose)
    on_sea = [a for a in anns if a.is_target and a.visibility > 0.5]
    assert on_sea
    uv, _ = project_points(intr, pose, np.array([a.position_ned for a in on_sea]))
    for a, (u, v) in zip(on_sea, uv, strict=True):
        x0, y0, x1, y1 = a.bbox_xyxy
        assert x0 - 1 <= u + 0.5 <= x1 + 1 and y0 - 1 <= v + 0.5 <= y1 + 1, a
        assert a.lat is not None and abs(a.lat - 54.17) < 0.01


def test_sea_moves_but_static_city_does_not(
    renderer: SceneRenderer, intr: CameraIntrinsics
) -> None:
    a, _ = renderer.render(1.0, _pose())
    b, _ = renderer.render(1.0 + 1 / 30, _pose())
    sea_change = np.mean(np.abs(a.astype(int) - b.astype(int)))
    city = Scenario(
        kind="urban",
        seed=3,
        area_ne=(0.0, -40.0, 60.0, 40.0),
        n_parked_cars=10,
        n_moving_cars=0,
        n_pedestrians=0,
    )
    urban = SceneRenderer(city, intr)
    c, anns = urban.render(1.0, _pose())
    d, _ = urban.render(1.0 + 1 / 30, _pose())
    city_change = np.mean(np.abs(c.astype(int) - d.astype(int)))
    assert sea_change > 1.5 * city_change
    assert city_change < 2.5
    assert any(x.category == "car" for x in anns)


def test_maritime_test_preset_fills_the_size_bands() -> None:
    preset = maritime_test()
    flight = Flight(preset.mission, seed=0)
    intr4k = preset.mission.camera.intrinsics()
    # Boxes do not depend on the image content: render small frames with the same camera scaled,
    # then scale the boxes back to 4K.
    small = intr4k.scaled(960, 540)
    renderer = SceneRenderer(preset.scenario, small)
    bands = [0, 0, 0]
    per_frame = []
    for t in np.linspace(2.0, flight.survey_duration - 2.0, 6):
        _, anns = renderer.render(float(t), flight.camera_pose_at(float(t)))
        targets = [a for a in anns if a.is_target]
        per_frame.append(len(targets))
        for a in targets:
            area = a.area * 16.0
            if area <= 64:
                bands[0] += 1
            elif area <= 256:
                bands[1] += 1
            elif area <= 1024:
                bands[2] += 1
    assert all(b > 0 for b in bands), bands
    assert 8 <= np.mean(per_frame) <= 16, per_frame


def test_generate_sequence_writes_coco_video(tmp_path, intr: CameraIntrinsics) -> None:
    preset = maritime_test()
    mission = replace(preset.mission, name="tiny")
    path = generate_sequence(
        preset.scenario,
        mission,
        frames=3,
        size=(320, 180),
        seed=0,
        out_dir=tmp_path,
        video=False,
        progress=False,
    )
    ds = read_coco_video(path)
    assert len(ds.images) == 3 and ds.images[0].telemetry.altitude == pytest.approx(90.0, abs=1)
    assert (tmp_path / ds.images[2].file_name).exists()
    assert {c.name for c in ds.categories} >= {"swimmer", "swimmer_with_life_jacket", "boat"}
    assert all(a.gt_lat is not None and a.track_id is not None for a in ds.annotations)
