"""The held-out scene generator: camera geometry, output format, boxes on what is drawn, seeds."""

from __future__ import annotations

import dataclasses
import json
import math
from collections import Counter
from pathlib import Path

import numpy as np
import pytest

from heldout.bodies import draw_look
from heldout.camera import Lens, View, ground_points, project
from heldout.generate import main as generate_main
from heldout.generate import render_world
from heldout.geodesy import lat_lon
from heldout.presets import draw_clip, world
from heldout.scene import ClipRenderer
from heldout.world import Thing
from sarmission.data.coco_video import read_coco_video
from sarmission.data.sequence import iter_sequence
from sarmission.geo.wgs84 import ned_to_geodetic


def test_nadir_camera_puts_its_heading_at_the_top_of_the_image() -> None:
    lens = Lens(640, 360, 60.0)
    view = View((10.0, -5.0, 80.0), heading_deg=90.0)  # looking down, facing east
    uv, depth = project(
        lens, view, np.array([[10.0, -5.0, 0.0], [30.0, -5.0, 0.0], [10.0, -25.0, 0.0]])
    )
    assert np.allclose(uv[0], [320, 180]) and np.allclose(depth, 80.0)
    assert uv[1, 1] < 180 and abs(uv[1, 0] - 320) < 1e-6  # east is up
    assert uv[2, 0] > 320 and abs(uv[2, 1] - 180) < 1e-6  # south is to the right


@pytest.mark.parametrize("tilt, roll", [(0.0, 0.0), (18.0, 0.0), (12.0, 2.5)])
def test_ground_points_and_projection_are_inverse(tilt: float, roll: float) -> None:
    lens = Lens(800, 450, 50.0)
    view = View((3.0, 4.0, 95.0), heading_deg=33.0, tilt_deg=tilt, roll_deg=roll)
    u = np.array([0.5, 400.0, 799.5, 123.25])
    v = np.array([0.5, 225.0, 449.5, 301.75])
    ground, ranges = ground_points(lens, view, u, v)
    uv, depth = project(lens, view, np.column_stack([ground, np.zeros(4)]))
    assert np.allclose(uv, np.column_stack([u, v]), atol=1e-6)
    assert np.all(ranges >= 95.0) and np.all(depth > 0)


def test_local_coordinates_agree_with_the_project_geodesy_to_a_centimetre() -> None:
    home = (43.2965, 5.3698)
    lat, lon = lat_lon(*home, east=250.0, north=-310.0)
    ref_lat, ref_lon, _ = ned_to_geodetic(-310.0, 250.0, 0.0, home[0], home[1], 0.0)
    metres_per_deg = 111_000.0
    assert abs(lat - ref_lat) * metres_per_deg < 0.01
    assert abs(lon - ref_lon) * metres_per_deg * math.cos(math.radians(home[0])) < 0.01


def test_render_world_writes_coco_video_that_the_evaluation_reads(tmp_path: Path) -> None:
    path = render_world("heldout_maritime", clips=2, frames=3, out=tmp_path, size=(320, 184))
    dataset = read_coco_video(path)
    assert [v.name for v in dataset.videos] == ["heldout_maritime_00", "heldout_maritime_01"]
    assert {c.name for c in dataset.categories} >= {"swimmer", "swimmer_with_life_jacket"}
    for video in dataset.videos:
        frames = list(iter_sequence(dataset, video.id))
        assert [f.image.frame_index for f in frames] == [0, 1, 2]
        assert frames[0].frame_bgr.shape == (184, 320, 3)
        telemetry = frames[1].image.telemetry
        assert telemetry.latitude is not None and telemetry.altitude is not None
        assert telemetry.time == pytest.approx(1 / 30)
    for ann in dataset.annotations:
        assert {"posture", "speed_m_s", "visibility", "is_target"} <= set(ann.extra)
        x, y, w, h = ann.bbox
        assert 0 <= x and 0 <= y and x + w <= 320 and y + h <= 184 and w > 0 and h > 0


def _clip_with_swimmers(offsets: list[tuple[float, float]]):
    spec = draw_clip(world("heldout_maritime"), 5, 640, 360, 1.0)
    view = spec.path.view(0.0)
    lens = spec.lens
    centre, _ = ground_points(lens, view, np.array([320.0]), np.array([180.0]))
    rng = np.random.default_rng(99)
    things = []
    for i, (de, dn) in enumerate(offsets):
        kind = "swimmer_with_life_jacket" if i % 2 else "swimmer"
        look = dataclasses.replace(draw_look(rng, kind, spec.sea.water_bgr), posture="upright")
        things.append(
            Thing(i + 1, look, (centre[0, 0] + de, centre[0, 1] + dn, 0.0), (0.0, 0.0), 0.0, 0.0)
        )
    return spec, tuple(things)


def test_targets_are_boxed_where_they_are_drawn() -> None:
    spec, things = _clip_with_swimmers([(-3.0, 0.0), (3.0, 1.5), (0.0, -3.0)])
    with_people = ClipRenderer(dataclasses.replace(spec, things=things))
    empty = ClipRenderer(dataclasses.replace(spec, things=()))
    frame, boxes = with_people.render(0.0, np.random.default_rng(1))
    background, none = empty.render(0.0, np.random.default_rng(1))
    assert none == []
    assert sorted(b.track_id for b in boxes) == [1, 2, 3]
    diff = np.abs(frame.astype(np.int16) - background.astype(np.int16)).max(axis=2)
    for box in boxes:
        x, y, w, h = (int(round(v)) for v in box.bbox)
        assert box.is_target and 3 <= max(w, h) <= 64
        assert diff[y : y + h, x : x + w].mean() > 8.0
        # the box centre projects from the swimmer's own position
        thing = things[box.track_id - 1]
        uv, _ = project(spec.lens, spec.path.view(0.0), np.array([thing.start]))
        assert abs(uv[0, 0] - (x + w / 2)) < max(w, 4) and abs(uv[0, 1] - (y + h / 2)) < max(h, 4)
    far = np.ones_like(diff, bool)
    for box in boxes:
        x, y, w, h = (int(round(v)) for v in box.bbox)
        far[max(0, y - 3 * h) : y + 4 * h, max(0, x - 3 * w) : x + 4 * w] = False
    assert diff[far].max() == 0  # nothing drawn away from the annotated people


@pytest.mark.parametrize("name, clip", [("heldout_maritime", 1), ("heldout_land", 0)])
def test_fully_visible_people_span_the_tiny_target_sizes(name: str, clip: int) -> None:
    spec = draw_clip(world(name), clip, 1920, 1080, 1.0)
    _, boxes = ClipRenderer(spec).render(0.0, np.random.default_rng(0))
    sides = [max(b.bbox[2], b.bbox[3]) for b in boxes if b.is_target and b.visibility == 1.0]
    assert sides and 4 <= min(sides) and max(sides) <= 64


def test_same_seed_renders_the_same_clip_and_another_clip_differs(tmp_path: Path) -> None:
    a = render_world("heldout_land", 1, 2, tmp_path / "a", size=(256, 144), images=True)
    b = render_world("heldout_land", 1, 2, tmp_path / "b", size=(256, 144), images=True)
    c = render_world(
        "heldout_land", 1, 2, tmp_path / "c", size=(256, 144), images=True, first_clip=1
    )
    assert json.loads(a.read_text()) == json.loads(b.read_text())
    for i in range(2):
        name = f"heldout_land_00/{i:06d}.jpg"
        assert (a.parent / name).read_bytes() == (b.parent / name).read_bytes()
    first_a = (a.parent / "heldout_land_00/000000.jpg").read_bytes()
    first_c = (c.parent / "heldout_land_01/000000.jpg").read_bytes()
    assert first_a != first_c


def test_a_lower_altitude_flies_the_same_clip_nearer_and_people_cover_more_pixels(
    tmp_path: Path,
) -> None:
    """``altitude_m`` replaces the world's range: the clip's altitude lies in it and its
    people's boxes grow as the altitude falls (the footprint shrinks, the density stays)."""

    def people_widths(altitude: tuple[float, float]) -> tuple[float, list[float]]:
        path = render_world(
            "heldout_maritime",
            1,
            1,
            tmp_path / f"{altitude[0]:g}",
            size=(640, 360),
            altitude_m=altitude,
        )
        dataset = read_coco_video(path)
        assert json.loads(path.read_text())["info"]["altitude_m"] == list(altitude)
        widths = [a.bbox[2] for a in dataset.annotations if a.extra["is_target"]]
        return float(dataset.videos[0].extra["altitude_m"]), widths

    high, high_widths = people_widths((110.0, 120.0))
    low, low_widths = people_widths((25.0, 30.0))
    assert 110.0 <= high <= 120.0 and 25.0 <= low <= 30.0
    assert high_widths and low_widths
    assert np.median(low_widths) > 3 * np.median(high_widths)


def test_command_line_rejects_a_bad_altitude_range_with_one_line(capsys) -> None:
    with pytest.raises(SystemExit):
        generate_main(["--altitude", "high", "--out", "/tmp/never-written"])
    assert "expected LOW,HIGH" in capsys.readouterr().err
    assert generate_main(["--altitude", "60,30", "--out", "/tmp/never-written"]) == 2
    assert "altitude range must be" in capsys.readouterr().err
    assert not Path("/tmp/never-written").exists()


def test_command_line_rejects_an_unknown_world_with_one_line(capsys) -> None:
    with pytest.raises(SystemExit):
        generate_main(["--world", "atlantis", "--out", "/tmp/never"])
    assert "invalid choice" in capsys.readouterr().err
    assert generate_main(["--clips", "0", "--out", "/tmp/never-written"]) == 2
    assert "at least one clip" in capsys.readouterr().err
    assert generate_main(["--fps", "0", "--out", "/tmp/never-written"]) == 2
    assert "fps must be positive" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("empty", "full"),
    [("heldout_land_empty", "heldout_land"), ("heldout_maritime_empty", "heldout_maritime")],
)
def test_background_only_worlds_keep_the_distractors_and_no_person(empty: str, full: str) -> None:
    kinds = Counter()
    for clip in range(4):
        kinds.update(t.look.kind for t in draw_clip(world(empty), clip, 1920, 1080, 1.0).things)
    assert not {"person", "swimmer", "swimmer_with_life_jacket"} & set(kinds)
    distractors = set(world(full).population.per_frame) - {
        "person",
        "swimmer",
        "swimmer_with_life_jacket",
    }
    assert set(kinds) <= distractors and len(kinds) >= 2
    assert world(empty).seed not in {world(n).seed for n in ("heldout_land", "heldout_maritime")}


def test_the_clutter_world_is_the_sea_s_distractors_denser_and_without_people() -> None:
    sea, clutter = world("heldout_maritime"), world("heldout_maritime_clutter")
    people = {"person", "swimmer", "swimmer_with_life_jacket"}
    assert not people & set(clutter.population.per_frame)
    for kind, density in clutter.population.per_frame.items():
        assert density >= 2 * sea.population.per_frame[kind]
    others = ("heldout_maritime", "heldout_land", "heldout_maritime_empty", "heldout_land_empty")
    assert clutter.seed not in {world(n).seed for n in others}
    kinds = Counter()
    for clip in range(2):
        kinds.update(t.look.kind for t in draw_clip(clutter, clip, 1920, 1080, 1.0).things)
    assert not people & set(kinds) and kinds["buoy"] >= 4
