"""m-of-k confirmation ("lock") of a trajectory.

A trajectory is locked at the first frame where at least ``m`` of the last ``k`` frames
(that frame included) were hits. That frame is always a hit: it is the m-th hit inside some
window of k consecutive frames. Once locked it stays locked. Defaults m=3, k=5 (paper 5.1).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Sequence


def _validate(m: int, k: int) -> None:
    if not 1 <= m <= k:
        raise ValueError(f"m-of-k lock needs 1 <= m <= k, got m={m}, k={k}")


class MofKLock:
    """Sliding window over one trajectory's last ``k`` hit/miss flags.

    ``update(hit)`` is called once per frame of the trajectory; ``lock_index`` is the 0-based
    update count at which the lock happened (``None`` until then).
    """

    def __init__(self, m: int = 3, k: int = 5) -> None:
        _validate(m, k)
        self.m, self.k = m, k
        self._window: deque[bool] = deque(maxlen=k)
        self.frames_seen = 0
        self.lock_index: int | None = None

    @property
    def locked(self) -> bool:
        """Whether the m-of-k condition has been met at some frame so far."""
        return self.lock_index is not None

    def update(self, hit: bool) -> bool:
        """Record this frame's hit or miss; return whether the trajectory is locked."""
        self._window.append(bool(hit))
        if self.lock_index is None and sum(self._window) >= self.m:
            self.lock_index = self.frames_seen
        self.frames_seen += 1
        return self.locked


def first_lock_index(hits: Sequence[bool], m: int = 3, k: int = 5) -> int | None:
    """Index of the first frame at which ``hits`` has ``m`` hits within the last ``k`` frames.

    ``None`` when that never happens. Equivalent to feeding ``hits`` to :class:`MofKLock`.
    """
    _validate(m, k)
    count = 0
    for i, hit in enumerate(hits):
        count += bool(hit)
        if i >= k:
            count -= bool(hits[i - k])
        if count >= m:
            return i
    return None
