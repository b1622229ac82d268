"""TTM-RPN: local maxima, top-N, forward shift, polarity, full-resolution geometry."""

from __future__ import annotations

import numpy as np
import pytest
from motion_scenes import drifting_scene, moving_target, sea_scene, textured_background, to_bgr

from sarmission.perception.rpn import TTMRPN
from sarmission.perception.types import MotionMaps
from sarmission.perception.vstmd import VSTMD


def final_maps(frames: list[np.ndarray], ds: int, target_size: float) -> MotionMaps:
    model = VSTMD(ds=ds, target_size=target_size)
    maps = None
    for f in frames:
        maps = model.step(f)
    return maps


def maps_from_response(response: np.ndarray, ds: int = 1) -> MotionMaps:
    z = np.zeros_like(response)
    return MotionMaps(ds, z, z, z, z, response)


def test_peaks_are_local_maxima_ranked_and_capped() -> None:
    rng = np.random.default_rng(0)
    r = (rng.random((60, 80)) ** 4).astype(np.float32)
    rpn = TTMRPN(topn=7, nms_size=3, min_score=0.0)
    rows, cols, scores = rpn.peaks(r)
    assert rows.size == 7
    assert np.all(np.diff(scores) <= 0)
    for i, j, s in zip(rows, cols, scores, strict=True):
        window = r[max(i - 1, 0) : i + 2, max(j - 1, 0) : j + 2]
        assert s == window.max()
    # No other local maximum beats the last kept one.
    padded = np.pad(r, 1)
    neigh = np.max(
        [padded[1 + dy : 61 + dy, 1 + dx : 81 + dx] for dy in (-1, 0, 1) for dx in (-1, 0, 1)],
        axis=0,
    )
    all_max = np.sort(r[r == neigh])[::-1]
    np.testing.assert_array_equal(scores, all_max[:7])


def test_plateaus_zeros_and_threshold() -> None:
    r = np.zeros((20, 20), np.float32)
    r[5, 5:7] = 1.0  # two-pixel plateau: one proposal
    r[12, 12] = 0.5
    r[15, 3] = 1e-9  # below min_score
    rows, cols, _ = TTMRPN(topn=10, min_score=1e-7).peaks(r)
    assert sorted(zip(rows.tolist(), cols.tolist(), strict=True)) == [(5, 5), (12, 12)]
    assert TTMRPN().peaks(np.zeros((8, 8), np.float32))[0].size == 0
    assert len(TTMRPN().propose(maps_from_response(np.zeros((8, 8), np.float32)))) == 0


def test_count_and_box_size() -> None:
    bg = textured_background(240, 320, seed=11)
    frames = []
    for t in range(12):
        img = bg.copy()
        for k, (x0, y0) in enumerate([(60, 60), (200, 80), (120, 180)]):
            f, _ = moving_target(
                240, 320, 1, (x0 + 2.0 * t, y0 + 0.5 * k * t), (0, 0), 8, background=img
            )
            img = f[0]
        frames.append(img)
    maps = final_maps(frames, 2, 8)
    for topn in (1, 2, 25):
        props = TTMRPN(topn=topn, box_size=16.0).propose(maps)
        assert 1 <= len(props) <= topn
        w = props.boxes[:, 2] - props.boxes[:, 0]
        h = props.boxes[:, 3] - props.boxes[:, 1]
        np.testing.assert_allclose(w, 16.0, atol=1e-4)
        np.testing.assert_allclose(h, 16.0, atol=1e-4)
        assert props.points.shape == (len(props), 2)
        assert props.scores.shape == props.theta.shape == props.polarity.shape == (len(props),)
    assert len(TTMRPN(topn=25).propose(maps)) >= 3


def test_forward_shift_moves_box_towards_target() -> None:
    raw, shifted = [], []
    for k in range(8):
        theta = k * np.pi / 4
        v = (2.0 * np.cos(theta), -2.0 * np.sin(theta))
        frames, centres = moving_target(
            200, 200, 12, (100 - 11 * v[0], 100 - 11 * v[1]), v, 8, seed=k
        )
        props = TTMRPN(topn=1, box_size=16.0).propose(final_maps(frames, 1, 8))
        assert len(props) == 1
        box_centre = props.boxes[0].reshape(2, 2).mean(axis=0)
        raw.append(np.linalg.norm(props.points[0] - centres[-1]))
        shifted.append(np.linalg.norm(box_centre - centres[-1]))
        # The shift is exactly 0.3 * S along theta (y up).
        d = box_centre - props.points[0]
        np.testing.assert_allclose(
            d, [4.8 * np.cos(props.theta[0]), -4.8 * np.sin(props.theta[0])], atol=1e-3
        )
    assert np.mean(shifted) < np.mean(raw)


def test_polarity_follows_contrast() -> None:
    bg = np.full((160, 200), 0.5, np.float32)
    got = {}
    for name, value in (("bright", 0.95), ("dark", 0.05)):
        frames, _ = moving_target(
            160, 200, 12, (70.0, 80.0), (2.0, 0.0), 8, value=value, background=bg
        )
        maps = final_maps(frames, 1, 8)
        props = TTMRPN(topn=1).propose(maps)
        x, y = props.points[0].astype(int)
        assert props.polarity[0] == float(maps.temporal_change[y, x] > 0)
        got[name] = props.polarity[0]
    assert got["bright"] != got["dark"]


@pytest.mark.parametrize("ds", [2, 4])
@pytest.mark.parametrize("shape", [(240, 320), (241, 317)])
def test_points_land_on_target_at_full_resolution(ds: int, shape: tuple[int, int]) -> None:
    size = 12
    frames, centres = moving_target(*shape, 14, (130.0, 121.0), (size / 4, 1.0), size, seed=6)
    maps = final_maps([to_bgr(f) for f in frames], ds, size)
    assert maps.response.shape == (shape[0] // ds, shape[1] // ds)
    props = TTMRPN(topn=3, box_size=16.0).propose(maps)
    assert len(props) >= 1
    assert np.linalg.norm(props.points[0] - centres[-1]) <= size + 4
    box_centre = props.boxes[0].reshape(2, 2).mean(axis=0)
    assert np.linalg.norm(box_centre - centres[-1]) <= size + 4


def test_invalid_arguments() -> None:
    with pytest.raises(ValueError):
        TTMRPN(topn=0)
    with pytest.raises(ValueError):
        TTMRPN(nms_size=4)
    with pytest.raises(ValueError):
        TTMRPN(box_size=0)


def test_flops() -> None:
    rpn = TTMRPN(topn=25)
    assert rpn.flops(1080, 1920) > 5 * 1080 * 1920
    assert rpn.flops(540, 960) < rpn.flops(1080, 1920)


@pytest.mark.parametrize("ds", [1, 2])
@pytest.mark.parametrize(
    ("start", "relative"),
    [((7.0, 100.0), (-2.0, 2.0)), ((150.0, 7.0), (0.0, -1.0)), ((296.0, 206.0), (-1.0, 0.0))],
)
def test_target_at_the_frame_edge_is_proposed_first(
    ds: int, start: tuple[float, float], relative: tuple[float, float]
) -> None:
    # A camera moving by (2, 1) px/frame over texture; the target ends 7 px from the left, 7 px
    # from the top (the new-content side) or 11-21 px from the right and bottom edges.
    frames, centres = drifting_scene(240, 320, 14, (2.0, 1.0), start, relative, 8.0, seed=3)
    maps = final_maps([to_bgr(f) for f in frames], ds, 8.0)
    props = TTMRPN(topn=5).propose(maps)
    assert len(props) >= 1
    assert np.linalg.norm(props.points[0] - centres[-1]) <= 8.0 + 4


def test_proposals_do_not_pile_up_on_the_frame_edge() -> None:
    # Sea-like clutter (texture, waves with their own motion, glints) from a moving camera: the
    # share of proposals in the 8-px strip along the frame edge stays near the strip's area share
    # (11 %), although the lobula counts pixels outside the map as zero.
    points = []
    for seed in range(3):
        frames, _ = sea_scene(240, 320, 16, (3.0, 1.5), (160.0, 120.0), (1.0, 0.0), 8.0, seed=seed)
        model = VSTMD(ds=2, target_size=8.0)
        for i, f in enumerate(frames):
            maps = model.step(to_bgr(f))
            if i >= 4:
                points.append(TTMRPN(topn=25).propose(maps).points)
    pts = np.concatenate(points)
    edge = np.minimum.reduce([pts[:, 0], pts[:, 1], 319 - pts[:, 0], 239 - pts[:, 1]])
    strip_share = 1.0 - (320 - 16) * (240 - 16) / (320 * 240)
    assert len(pts) >= 50
    assert np.mean(edge < 8) <= 2.0 * strip_share


def chroma_with_peaks(shape: tuple[int, int], peaks: list[tuple[int, int, float]]) -> np.ndarray:
    """A chroma map (1/8 resolution), zero but for the given ``(row, col, value)`` maxima."""
    chroma = np.zeros(shape, np.float32)
    for row, col, value in peaks:
        chroma[row, col] = value
    return chroma


def test_colour_slots_take_chroma_maxima_away_from_motion_points() -> None:
    response = np.zeros((80, 80), np.float32)  # ds 2: a 160 x 160 frame
    for k, (row, col) in enumerate([(10, 10), (10, 40), (40, 10), (40, 40), (70, 70)]):
        response[row, col] = 1.0 - 0.1 * k
    maps = maps_from_response(response, ds=2)
    # 20 x 20 chroma map; (2, 2) sits on the first motion point (x = y = 19.5 vs 20.5).
    chroma = chroma_with_peaks(
        (20, 20), [(2, 2, 50.0), (15, 5, 40.0), (5, 15, 30.0), (17, 17, 20.0)]
    )
    rpn = TTMRPN(topn=5, colour_share=0.4)
    assert rpn.colour_slots == 2
    props = rpn.propose(maps, chroma)
    assert len(props) == 5
    np.testing.assert_array_equal(props.source, [0, 0, 0, 1, 1])
    np.testing.assert_array_equal(props.from_colour, [False, False, False, True, True])
    # The colour proposals: the two strongest maxima not within 0.75 S of a kept motion point,
    # boxes of side S centred on them (no forward shift), scored with the chroma value.
    np.testing.assert_allclose(props.points[3:], [[43.5, 123.5], [123.5, 43.5]])
    centres = (props.boxes[3:, :2] + props.boxes[3:, 2:]) / 2
    np.testing.assert_allclose(centres, props.points[3:])
    np.testing.assert_allclose(props.boxes[3:, 2] - props.boxes[3:, 0], 16.0)
    np.testing.assert_allclose(props.scores[3:], [40.0, 30.0])


def test_empty_colour_slots_go_back_to_motion_and_share_zero_ignores_colour() -> None:
    response = np.zeros((80, 80), np.float32)
    for k in range(6):
        response[10 + 10 * k, 20] = 1.0 - 0.1 * k
    maps = maps_from_response(response, ds=2)
    flat = np.zeros((20, 20), np.float32)  # no anomaly anywhere (a grey frame)
    props = TTMRPN(topn=5, colour_share=0.4).propose(maps, flat)
    assert len(props) == 5 and not props.from_colour.any()
    chroma = chroma_with_peaks((20, 20), [(18, 18, 9.0)])
    only_motion = TTMRPN(topn=5, colour_share=0.0).propose(maps, chroma)
    assert len(only_motion) == 5 and not only_motion.from_colour.any()
    # Few motion maxima: colour proposals may fill more than their share.
    sparse = np.zeros((80, 80), np.float32)
    sparse[40, 40] = 1.0
    mixed = TTMRPN(topn=5, colour_share=0.2).propose(
        maps_from_response(sparse, ds=2),
        chroma_with_peaks((20, 20), [(2, 2, 5.0), (2, 17, 4.0), (17, 2, 3.0)]),
    )
    np.testing.assert_array_equal(mixed.source, [0, 1, 1, 1])


def test_colour_parameters_are_checked() -> None:
    with pytest.raises(ValueError, match="colour_share"):
        TTMRPN(colour_share=1.5)
    with pytest.raises(ValueError, match="colour_nms"):
        TTMRPN(colour_nms=2)
