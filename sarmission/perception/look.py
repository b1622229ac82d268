"""How much an object's look changes over about a second.

A swimmer's arms and head move against the water; a floating object's look stays the same
while it bobs and drifts. Each sighting keeps a small grey patch around its detection
(:func:`grey_patch`, resampled to :data:`PATCH_PX` px square so that a 4K frame and a small one
compare alike); :class:`LookMemory` compares it with the same object's patch about ``lag_s``
earlier, kept per target rather than per track, since a faint object's tracks break and
re-form within a second. :func:`look_change` is 1 - the best normalised correlation over a few
pixels of shift, so that the detection's jitter is not taken for a change. The confirmation
takes the median over a candidate's sightings (``[confirm] min_look_change``).
"""

from __future__ import annotations

import math
from collections import deque

import cv2
import numpy as np

from sarmission.yuv import YuvImage

#: Side of the compared patch in pixels.
PATCH_PX = 16
#: Shift searched (patch pixels) when two patches are compared: the detection's jitter.
SHIFT_PX = 2
#: The patch spans this many times the box's longer side (at least PATCH_PX frame pixels).
PATCH_PER_BOX = 1.5
#: A patch flatter than this (grey levels, standard deviation) shows nothing to compare.
FLAT = 1.0


def grey_patch(frame: np.ndarray | YuvImage, box: np.ndarray) -> np.ndarray | None:
    """The grey patch (float32, :data:`PATCH_PX` square) centred on ``box`` ``[x1, y1, x2,
    y2]``; None when it does not lie wholly inside the frame or the box is not finite."""
    x1, y1, x2, y2 = (float(v) for v in box)
    if not all(math.isfinite(v) for v in (x1, y1, x2, y2)):
        return None
    half = max(PATCH_PX / 2, PATCH_PER_BOX * max(x2 - x1, y2 - y1) / 2)
    cx, cy = (x1 + x2) / 2, (y1 + y2) / 2
    c0, r0 = int(round(cx - half)), int(round(cy - half))
    side = int(round(2 * half))
    if isinstance(frame, YuvImage):
        plane, height, width = frame.y, frame.height, frame.width
    else:
        plane, (height, width) = frame, frame.shape[:2]
    if c0 < 0 or r0 < 0 or c0 + side > width or r0 + side > height:
        return None
    window = plane[r0 : r0 + side, c0 : c0 + side]
    if window.ndim == 3:
        window = cv2.cvtColor(np.ascontiguousarray(window), cv2.COLOR_BGR2GRAY)
    patch = np.asarray(window, np.float32)
    if side != PATCH_PX:
        patch = cv2.resize(patch, (PATCH_PX, PATCH_PX), interpolation=cv2.INTER_AREA)
    return patch


def look_change(first: np.ndarray, second: np.ndarray, shift: int = SHIFT_PX) -> float | None:
    """1 - the best normalised correlation of ``first``'s centre (``shift`` px in from each
    side) with ``second`` over shifts of up to ``shift`` px: 0 the same look, about 1 none in
    common; None when either patch is flat."""
    if first.std() < FLAT or second.std() < FLAT:
        return None
    centre = np.ascontiguousarray(first[shift:-shift, shift:-shift])
    best = float(cv2.matchTemplate(second, centre, cv2.TM_CCOEFF_NORMED).max())
    return 1.0 - best


class LookMemory:
    """Each object's patches (by any key: the controller's target id) of the last ``lag_s`` +
    ``tolerance_s`` seconds, so that a new sighting is compared with the one ``lag_s`` (up to
    ``tolerance_s`` more) before it."""

    def __init__(self, lag_s: float = 1.0, tolerance_s: float = 0.25) -> None:
        self.lag_s = lag_s
        self.tolerance_s = tolerance_s
        self._patches: dict[int, deque[tuple[float, np.ndarray]]] = {}

    def change(self, key: int, t: float, patch: np.ndarray | None) -> float | None:
        """Keep ``patch`` (seen at ``t``) for ``key``; the look change against its patch
        closest to ``lag_s`` earlier (None: none that old, or a flat patch)."""
        kept = self._patches.setdefault(key, deque())
        while kept and kept[0][0] < t - self.lag_s - self.tolerance_s:
            kept.popleft()
        if patch is None:
            return None
        before = next((p for t0, p in reversed(kept) if t0 <= t - self.lag_s), None)
        kept.append((t, patch))
        return None if before is None else look_change(before, patch)

    def forget_before(self, t: float) -> None:
        """Forget the objects with no patch since ``t`` - ``lag_s`` - ``tolerance_s`` (out of
        sight, decided or gone): nothing they kept can be compared any more."""
        since = t - self.lag_s - self.tolerance_s
        for key in [k for k, kept in self._patches.items() if not kept or kept[-1][0] < since]:
            del self._patches[key]
