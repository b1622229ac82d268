"""The alternative training world: its camera, its figures' boxes, its clips and its isolation."""

from __future__ import annotations

import ast
import math
from pathlib import Path

import cv2
import numpy as np
import pytest

from altworld.camera import View, local_affine, project
from altworld.canvas import Canvas, place
from altworld.clip import HEIGHT, WIDTH, render_clip
from altworld.generate import main as generate_main
from altworld.generate import render_world
from sarmission.data.coco_video import read_coco_video

ALTWORLD = Path(__file__).resolve().parents[1] / "altworld"


def test_nadir_camera_puts_its_heading_at_the_top_and_east_to_the_right() -> None:
    view = View(
        east=10.0,
        north=20.0,
        height=50.0,
        heading_deg=0.0,
        tilt_deg=0.0,
        roll_deg=0.0,
        hfov_deg=60.0,
    )
    h = view.homography()
    assert project(h, 10.0, 20.0) == pytest.approx((960.0, 540.0))
    u, v = project(h, 11.0, 20.0)
    assert u - 960.0 == pytest.approx(view.focal / 50.0) and v == pytest.approx(540.0)
    u, v = project(h, 10.0, 21.0)
    assert u == pytest.approx(960.0) and 540.0 - v == pytest.approx(view.focal / 50.0)


def test_a_tilted_camera_looks_along_its_heading() -> None:
    view = View(0.0, 0.0, 80.0, heading_deg=90.0, tilt_deg=30.0, roll_deg=0.0, hfov_deg=70.0)
    ahead = 80.0 * math.tan(math.radians(30.0))
    assert project(view.homography(), ahead, 0.0) == pytest.approx((960.0, 540.0), abs=1e-6)


@pytest.mark.parametrize(("tilt", "roll"), [(0.0, 0.0), (25.0, 3.0), (35.0, -2.0)])
def test_ground_of_pixels_inverts_the_projection(tilt: float, roll: float) -> None:
    view = View(3.0, -4.0, 60.0, heading_deg=130.0, tilt_deg=tilt, roll_deg=roll, hfov_deg=75.0)
    east, north = view.ground_of_pixels()
    h = view.homography()
    for v, u in [(0, 0), (540, 960), (1079, 1919), (200, 1500)]:
        assert project(h, float(east[v, u]), float(north[v, u])) == pytest.approx(
            (u + 0.5, v + 0.5), abs=0.05
        )


def test_local_affine_is_the_projections_derivative() -> None:
    view = View(0.0, 0.0, 40.0, heading_deg=200.0, tilt_deg=30.0, roll_deg=1.0, hfov_deg=65.0)
    h = view.homography()
    jac = local_affine(h, 5.0, -7.0)
    step = 1e-4
    for axis, (de, dn) in enumerate([(step, 0.0), (0.0, step)]):
        a, b = project(h, 5.0 + de, -7.0 + dn), project(h, 5.0 - de, -7.0 - dn)
        assert jac[:, axis] == pytest.approx(
            [(a[0] - b[0]) / (2 * step), (a[1] - b[1]) / (2 * step)], rel=1e-4
        )


def test_a_figure_is_boxed_at_its_drawn_size() -> None:
    """A 1 m x 0.5 m ellipse at 20 px per metre, heading north, boxes about 20 x 10 px; one at
    heading 90 turns the box; effects (not body) do not widen it."""
    frame = np.zeros((200, 200, 3), np.float32)
    canvas = Canvas(2.0, 60.0)
    canvas.ellipse(0, 0, 0.9, 0.9, 0, (0, 0, 255), 0.3, body=False)
    canvas.ellipse(0, 0, 0.25, 0.5, 0, (255, 255, 255))
    jac = np.array([[20.0, 0.0], [0.0, -20.0]])
    x, y, w, h = place(frame, canvas, jac, (100.0, 100.0), 0.0)
    assert (w, h) == pytest.approx((10.0, 20.0), abs=2.0)
    assert (x + w / 2, y + h / 2) == pytest.approx((100.0, 100.0), abs=1.0)
    assert frame[100, 100].min() > 200  # the body is drawn
    assert frame[100, 115, 2] > 30 and frame[100, 115, 0] < 5  # the unboxed effect too
    _, _, w, h = place(np.zeros((200, 200, 3), np.float32), canvas, jac, (100.0, 100.0), 90.0)
    assert (w, h) == pytest.approx((20.0, 10.0), abs=2.0)


def test_a_figure_outside_the_frame_has_no_box() -> None:
    canvas = Canvas(1.0, 30.0)
    canvas.ellipse(0, 0, 0.3, 0.3, 0, (255, 255, 255))
    assert (
        place(np.zeros((50, 50, 3), np.float32), canvas, np.eye(2) * 10, (500.0, 500.0), 0.0)
        is None
    )


@pytest.mark.parametrize("world", ["sea", "land"])
def test_clips_are_readable_video_with_boxes_inside_the_frame(tmp_path: Path, world: str) -> None:
    path = render_world(world, clips=1, frames=4, out=tmp_path, log=lambda _: None)
    dataset = read_coco_video(path)
    assert len(dataset.images) == 4
    capture = cv2.VideoCapture(str(tmp_path / f"altworld_{world}_00.mp4"))
    count = 0
    while True:
        ok, frame = capture.read()
        if not ok:
            break
        assert frame.shape == (HEIGHT, WIDTH, 3)
        count += 1
    assert count == 4
    names = {c.id: c.name for c in dataset.categories}
    people = {"sea": {"swimmer", "swimmer_with_life_jacket"}, "land": {"person"}}[world]
    assert any(names[a.category_id] in people for a in dataset.annotations)
    for a in dataset.annotations:
        x, y, w, h = a.bbox
        assert (
            0 <= x
            and 0 <= y
            and x + w <= WIDTH + 1e-6
            and y + h <= HEIGHT + 1e-6
            and w >= 2
            and h >= 2
        )


def test_a_drawn_person_is_where_its_box_says(tmp_path: Path) -> None:
    """Inside a person's box the frame differs from the ground around it."""
    images, boxes = render_clip(9_320_003, "land", 1, tmp_path / "clip.mp4")
    capture = cv2.VideoCapture(str(tmp_path / "clip.mp4"))
    ok, frame = capture.read()
    assert ok and images and boxes
    people = [b for b in boxes if b["category"] == "person" and min(b["bbox"][2:]) >= 6]
    assert people
    contrast = []
    for b in people:
        x, y, w, h = (int(round(v)) for v in b["bbox"])
        inside = frame[y : y + h, x : x + w].reshape(-1, 3).astype(float)
        ring = (
            frame[max(y - h, 0) : y + 2 * h, max(x - w, 0) : x + 2 * w].reshape(-1, 3).astype(float)
        )
        contrast.append(np.abs(inside.mean(0) - np.median(ring, 0)).max() + inside.std(0).max())
    assert np.median(contrast) > 10


def test_the_same_seed_renders_the_same_boxes_and_another_seed_differs(tmp_path: Path) -> None:
    _, a = render_clip(9_310_001, "sea", 3, tmp_path / "a.mp4")
    _, b = render_clip(9_310_001, "sea", 3, tmp_path / "b.mp4")
    _, c = render_clip(9_310_002, "sea", 3, tmp_path / "c.mp4")
    assert a == b and a != c


def test_command_line_rejects_bad_requests_with_one_line(tmp_path: Path, capsys) -> None:
    assert generate_main(["--world", "sea", "--clips", "0", "--out", str(tmp_path)]) == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("error:") and "\n" not in err
    with pytest.raises(SystemExit):
        generate_main(["--world", "moon", "--out", str(tmp_path)])


def test_the_world_imports_no_other_renderer_and_no_sarmission() -> None:
    for source in ALTWORLD.glob("*.py"):
        tree = ast.parse(source.read_text())
        for node in ast.walk(tree):
            names = []
            if isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            elif isinstance(node, ast.ImportFrom):
                names = [node.module or ""]
            for name in names:
                assert name.split(".")[0] not in {"sim", "heldout", "sarmission"}, (
                    source.name,
                    name,
                )


def test_without_ffmpeg_clips_are_written_by_opencv(tmp_path: Path, monkeypatch) -> None:
    monkeypatch.setattr("altworld.encode.shutil.which", lambda _: None)
    render_clip(9_310_004, "sea", 3, tmp_path / "clip.mp4")
    capture = cv2.VideoCapture(str(tmp_path / "clip.mp4"))
    assert int(capture.get(cv2.CAP_PROP_FRAME_COUNT)) == 3
    assert capture.read()[1].shape == (HEIGHT, WIDTH, 3)
