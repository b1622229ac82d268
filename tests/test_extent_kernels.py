"""The object extent's region loop gives what the same steps give through numpy and OpenCV
(border histograms, a distance table, a 3 x 3 closing, 8-connected components), on windows of
every kind: nothing standing out, a mixed border, regions cut by the window, ties between
components under the box. The compiled loop and the JIT agree."""

import cv2
import numpy as np
import pytest

from sarmission.perception import extent, extent_kernels, kernels


def reference_region(lab: np.ndarray, inner, threshold: float, spread_floor: float, share: float):
    """The region as numpy and OpenCV compute it, in the kernel's result format."""
    h, w = lab.shape[:2]
    band = max(2, min(h, w) // 16)
    on_border = np.zeros((h, w), bool)
    on_border[:band], on_border[h - band :] = True, True
    on_border[:, :band], on_border[:, w - band :] = True, True
    border = lab[on_border]
    outlying = np.zeros((3, 256), bool)
    values = np.arange(256)
    for c in range(3):
        median = int(np.sort(border[:, c])[(len(border) - 1) // 2])  # the lower median
        deviation = np.abs(border[:, c].astype(int) - median)
        mad = int(np.sort(deviation)[(len(deviation) - 1) // 2])
        outlying[c] = np.abs(values - median) / (1.4826 * mad + spread_floor) > threshold
    mask = (outlying[0][lab[..., 0]] | outlying[1][lab[..., 1]] | outlying[2][lab[..., 2]]).astype(
        np.uint8
    )
    if mask[on_border].mean() > share:
        return extent_kernels.MIXED, 0, 0, 0, 0, False
    closed = cv2.morphologyEx(mask, cv2.MORPH_CLOSE, np.ones((3, 3), np.uint8))
    _, labels, stats, _ = cv2.connectedComponentsWithStats(closed, connectivity=8)
    x0, y0, x1, y1 = inner
    counts = np.bincount(labels[y0:y1, x0:x1].ravel(), minlength=len(stats))
    counts[0] = 0
    if not counts.any():
        return extent_kernels.NOTHING, 0, 0, 0, 0, False
    left, top, width, height = (int(v) for v in stats[int(np.argmax(counts)), :4])
    right, bottom = left + width, top + height
    touches = left <= 0 or top <= 0 or right >= w or bottom >= h
    return extent_kernels.FOUND, left, top, right, bottom, touches


def random_window(rng: np.random.Generator):
    """A noisy background with a few ellipses, its Lab, and a box inside it."""
    h, w = (int(v) for v in rng.integers(8, 120, 2))
    base = rng.integers(0, 256, 3)
    noise = rng.normal(0, rng.uniform(1, 25), (h, w, 3))
    bgr = np.clip(base + noise, 0, 255).astype(np.uint8)
    for _ in range(int(rng.integers(0, 6))):
        centre = (int(rng.integers(0, w)), int(rng.integers(0, h)))
        axes = (int(rng.integers(1, 30)), int(rng.integers(1, 10)))
        colour = tuple(int(v) for v in rng.integers(0, 256, 3))
        cv2.ellipse(bgr, centre, axes, float(rng.uniform(0, 180)), 0, 360, colour, -1)
    x0, y0 = int(rng.integers(0, w - 1)), int(rng.integers(0, h - 1))
    inner = (x0, y0, int(rng.integers(x0 + 1, w + 1)), int(rng.integers(y0 + 1, h + 1)))
    return cv2.cvtColor(bgr, cv2.COLOR_BGR2LAB), inner


def test_the_region_loop_matches_numpy_and_opencv_on_every_kind_of_window():
    rng = np.random.default_rng(7)
    seen = set()
    for _ in range(1500):
        lab, inner = random_window(rng)
        threshold = float(rng.choice([2.5, 3.5, 4.5]))
        share = float(rng.choice([0.05, 0.1, 0.5]))
        want = reference_region(lab, inner, threshold, 3.0, share)
        got = kernels.extent_region(lab, *inner, threshold, 3.0, share)
        assert tuple(got) == want, (lab.shape, inner, threshold, share)
        seen.add((want[0], want[5]))
    # every outcome was exercised: nothing, mixed, found inside and found touching the edge
    assert seen == {
        (extent_kernels.NOTHING, False),
        (extent_kernels.MIXED, False),
        (extent_kernels.FOUND, False),
        (extent_kernels.FOUND, True),
    }


def test_a_tie_under_the_box_goes_to_the_component_opencv_labels_first():
    lab = np.full((40, 40, 3), 128, np.uint8)
    lab[20, 10:13] = 250  # three pixels under the box, in the lower row pair ...
    lab[19, 26:29] = 250  # ... and three in the upper one, further right
    inner = (8, 19, 31, 21)
    want = reference_region(lab, inner, 3.5, 3.0, 0.1)
    assert want[1:5] == (26, 19, 29, 20)  # OpenCV scans rows in pairs, column by column
    assert tuple(kernels.extent_region(lab, *inner, 3.5, 3.0, 0.1)) == want


def test_extent_reads_the_loops_result_codes():
    assert (extent._NOTHING, extent._MIXED) == (extent_kernels.NOTHING, extent_kernels.MIXED)
    assert extent_kernels.FOUND not in (extent._NOTHING, extent._MIXED)


@pytest.mark.parametrize("seed", [3, 11])
def test_the_compiled_region_loop_matches_the_jit(seed: int):
    if kernels.backend_name() != "aot":
        pytest.skip("the loops did not compile ahead of time here")
    rng = np.random.default_rng(seed)
    for _ in range(200):
        lab, inner = random_window(rng)
        args = (*inner, 3.5, 3.0, 0.1)
        assert tuple(kernels.backend().extent_region(lab, *args)) == tuple(
            extent_kernels.region(lab, *args)
        )
