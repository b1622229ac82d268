"""Figures with height in the simulator: an upright part's pixel height follows the pinhole
camera worked by hand, it shrinks to nothing seen from straight above, oblique swimmers are
boxes of real proportions and sizes, and the oblique presets' swimmer widths sit inside the
real SeaDronesSee file's range."""

import json
import math
from pathlib import Path

import numpy as np
import pytest

from sarmission.geo.camera import CameraIntrinsics, CameraPose
from sarmission.geo.frames import rotation_ned_from_camera
from sim.render import SceneRenderer
from sim.scenarios import preset
from sim.scene import Part, Scenario, SceneObject, Upright, World

INTR = CameraIntrinsics.from_hfov(640, 360, 70.0)
REAL = (
    Path(__file__).resolve().parents[2]
    / "shared"
    / "datasets"
    / "seadronessee"
    / "instances_val.json"
)


def camera(depression_deg: float, height_m: float, heading_deg: float = 0.0) -> CameraPose:
    rotation = rotation_ned_from_camera(
        (0.0, 0.0, 0.0), (0.0, -math.radians(depression_deg), math.radians(heading_deg)), "earth"
    )
    return CameraPose(np.array([0.0, 0.0, -height_m]), rotation)


def pole_world(north: float, flat: list[Part], upright: list[Upright]) -> World:
    scenario = Scenario(
        kind="maritime",
        seed=3,
        area_ne=(-5.0, -5.0, 60.0, 5.0),
        n_swimmers=0,
        n_life_jacket=0,
        n_boats=0,
        n_birds=0,
        n_debris=0,
        n_glints=0,
        figures="upright",
    )
    return World(scenario, [SceneObject(1, "buoy", (north, 0.0), 0.0, flat, upright=upright)])


def box_of(world: World, pose: CameraPose) -> tuple[float, float, float, float]:
    _, annotations = SceneRenderer(world.scenario, INTR, world=world).render(0.0, pose)
    assert len(annotations) == 1
    return annotations[0].bbox_xyxy


@pytest.mark.parametrize(("distance", "tall"), [(20.0, 2.0), (40.0, 3.0)])
def test_an_upright_pole_is_as_tall_as_the_pinhole_says(distance, tall):
    # Camera 1 m above the water looking level, a 0.2 m thick pole ``tall`` metres high and
    # ``distance`` ahead: by similar triangles its image spans rows cy + f (1 - tall) / d to
    # cy + f / d, and columns cx -+ f 0.1 / d.
    pole = [Upright("box", 0.0, 0.0, 0.1, 0.1, 0.0, tall, (40, 200, 240))]
    x0, y0, x1, y1 = box_of(pole_world(distance, [], pole), camera(0.0, 1.0))
    f = INTR.fx
    assert y1 - y0 == pytest.approx(f * tall / distance, rel=0.02)
    assert y1 == pytest.approx(INTR.cy + 0.5 + f * 1.0 / distance, abs=0.6)
    assert x1 - x0 == pytest.approx(f * 0.2 / distance, rel=0.05)


def test_seen_from_straight_above_only_the_flat_parts_make_the_box():
    flat = [Part("ellipse", 0.0, 0.0, 0.6, 0.6, 0.0, (40, 200, 240))]
    pole = [Upright("box", 0.0, 0.0, 0.1, 0.1, 0.0, 3.0, (40, 40, 40))]
    above = camera(90.0, 30.0)
    with_pole = box_of(pole_world(0.0, flat, pole), above)
    without = box_of(pole_world(0.0, flat, []), above)
    assert with_pole == pytest.approx(without, abs=1e-6)
    # Off to the side (about 45 degrees down), the pole rises above the disc in the image.
    side = box_of(pole_world(30.0, flat, pole), camera(45.0, 30.0))
    disc = box_of(pole_world(30.0, flat, []), camera(45.0, 30.0))
    assert side[1] < disc[1] - 0.3 * INTR.fx * 3.0 / math.hypot(30.0, 30.0)


def oblique_swimmers(name: str, frames: int = 4) -> list[tuple[float, float, float]]:
    """(box width px, box height px, slant range m) of clear swimmers in a few frames."""
    from sim.flight import Flight

    chosen = preset(name)
    flight = Flight(chosen.mission, seed=chosen.scenario.seed)
    intr = chosen.mission.camera.intrinsics().scaled(640, 360)
    renderer = SceneRenderer(chosen.scenario, intr)
    found = []
    for k in range(frames):
        pose = flight.state_at(5.0 + 5.0 * k).camera_pose()
        for a in renderer.render(5.0 + 5.0 * k, pose)[1]:
            x0, y0, x1, y1 = a.bbox_xyxy
            inside = x0 > 1 and y0 > 1 and x1 < intr.width - 1 and y1 < intr.height - 1
            if a.is_target and a.visibility > 0.6 and inside:
                slant = float(np.linalg.norm(np.array(a.position_ned) - pose.position_ned))
                found.append((x1 - x0, y1 - y0, slant))
    return found


def test_oblique_swimmers_stand_out_of_the_water_at_real_sizes():
    swimmers = np.array(oblique_swimmers("maritime_oblique_low"))
    assert len(swimmers) >= 8
    f = 320.0 / math.tan(math.radians(35.0))
    metres = swimmers[:, 0] * swimmers[:, 2] / f
    # SeaDronesSee's swimmer boxes are 0.6 / 1.0 / 1.9 m wide (p10 / p50 / p90) taking a
    # 70 degree lens; flat figures 11 degrees down were 4 % as tall as wide.
    assert 0.3 < np.percentile(metres, 10) and np.percentile(metres, 90) < 2.2
    assert 0.6 < np.median(metres) < 1.4
    assert np.median(swimmers[:, 1] / swimmers[:, 0]) > 0.25


@pytest.mark.skipif(not REAL.is_file(), reason="the SeaDronesSee file is not here")
def test_oblique_preset_swimmer_widths_sit_in_the_real_range():
    data = json.loads(REAL.read_text())
    width_of = {im["id"]: im["width"] for im in data["images"]}
    real = [
        a["bbox"][2] * 3840.0 / width_of[a["image_id"]]
        for a in data["annotations"]
        if a["category_id"] == 1
    ]
    r10, r50, r90 = np.percentile(real, [10, 50, 90])
    simulated = [
        w * 3840.0 / 640.0
        for name in ("maritime_oblique_low", "maritime_oblique_mid", "maritime_oblique_high")
        for w, _, _ in oblique_swimmers(name, 3)
    ]
    s50 = float(np.median(simulated))
    assert r10 < s50 < r90
    assert 0.6 * r50 < s50 < 1.6 * r50


def test_the_maritime_classes_of_real_footage_are_in_the_oblique_world():
    from sim.upright_world import build_upright_world

    world = build_upright_world(preset("maritime_oblique_mid").scenario)
    categories = {o.category for o in world.objects}
    assert {"swimmer", "boat", "jetski", "buoy", "life_saving_appliances"} <= categories
    assert not any(
        o.is_target
        for o in world.objects
        if o.category in ("boat", "jetski", "buoy", "life_saving_appliances")
    )
    people = [o for o in world.objects if o.is_target]
    assert people and all(o.upright for o in people)


def test_the_objects_training_preset_shows_every_object_class_in_each_frame():
    """maritime_objects_train exists so that a head sees enough of each class that is no
    swimmer: every frame shows buoys, life rings and jetskis beside the swimmers."""
    from sim.flight import Flight

    chosen = preset("maritime_objects_train")
    assert chosen.scenario.seed not in {
        preset(n).scenario.seed
        for n in ("maritime_oblique_low", "maritime_oblique_mid", "maritime_oblique_high")
    }
    flight = Flight(chosen.mission, seed=chosen.scenario.seed)
    intr = chosen.mission.camera.intrinsics().scaled(640, 360)
    renderer = SceneRenderer(chosen.scenario, intr)
    for t in (0.0, 2.0):
        seen = {a.category for a in renderer.render(t, flight.state_at(t).camera_pose())[1]}
        assert {"swimmer", "jetski", "buoy", "life_saving_appliances"} <= seen, (t, seen)
