"""The head's verdict averaged over several orientations of each crop (test-time symmetry).

Seen from above, a person has no preferred orientation in the picture, and the head is trained
on each crop turned and mirrored at random (the 8 symmetries of the square). Scoring a crop in
several of those orientations and averaging what the head says (class probabilities, and its
box turned back into the crop's own frame) takes away the part of a score that depends on how a
target happened to lie. Measured on held-out footage: docs/experiments.md (off by default).

Symmetry ``op`` in 0..7: ``op % 4`` quarter turns (counter-clockwise, as ``numpy.rot90`` on the
crop's last two axes), then a left-right mirror when ``op >= 4``; the training's augmentation
uses the same numbering.
"""

from __future__ import annotations

import numpy as np

#: ``l, t, r, b`` index permutation of a crop's box after one quarter turn and after a mirror:
#: ``ltrb_turned = ltrb[ROT90_LTRB]``.
ROT90_LTRB = (1, 2, 3, 0)
MIRROR_LTRB = (2, 1, 0, 3)
#: How many orientations a detector may average: none, the quarter turns, or all 8 symmetries.
ORIENTATION_COUNTS = (1, 4, 8)
_UNTURN_LTRB = (3, 0, 1, 2)


def oriented_crops(crops: np.ndarray, op: int) -> np.ndarray:
    """``crops`` ``[N, C, S, S]`` in orientation ``op`` (a new contiguous array)."""
    out = np.rot90(crops, op % 4, axes=(2, 3))
    if op >= 4:
        out = out[:, :, :, ::-1]
    return np.ascontiguousarray(out)


def ltrb_from_orientation(ltrb: np.ndarray, op: int) -> np.ndarray:
    """Edge distances ``[N, 4]`` predicted on crops in orientation ``op``, in the crops' own
    orientation (the inverse of what ``op`` does to a box)."""
    out = ltrb[:, MIRROR_LTRB] if op >= 4 else ltrb
    for _ in range(op % 4):
        out = out[:, _UNTURN_LTRB]
    return out


def check_orientations(count: int) -> int:
    """``count`` as an int, or ``ValueError`` unless it is one of :data:`ORIENTATION_COUNTS`."""
    if isinstance(count, bool) or int(count) != count or int(count) not in ORIENTATION_COUNTS:
        names = ", ".join(map(str, ORIENTATION_COUNTS))
        raise ValueError(f"orientations must be one of {names}, got {count!r}")
    return int(count)
