"""Plain data objects passed between the perception stages and out of MITE-Net."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np


@dataclass
class MotionMaps:
    """vSTMD state read out for one frame, all at 1/ds resolution (float32, shape ``[h, w]``).

    ``temporal_change`` is the signed lamina output L (after pooling by ds), ``v_on`` / ``v_off``
    the medulla membrane potentials, ``correlation`` their product C, ``response`` the lobula
    output R (after the size-selective DoG inhibition and rectification).
    """

    ds: int
    temporal_change: np.ndarray
    v_on: np.ndarray
    v_off: np.ndarray
    correlation: np.ndarray
    response: np.ndarray


#: :attr:`Proposals.source` values.
MOTION, COLOUR = 0, 1
#: The vSTMD pooling factors (power-saving mode): one source for the model, the mission file
#: and the command line.
VALID_DS = (1, 2, 4, 8)
#: Share of the N proposals that come from the chromatic anomaly map by default
#: (:class:`~sarmission.perception.rpn.TTMRPN`).
DEFAULT_COLOUR_SHARE = 0.4
#: Crop sides (multiples of the proposal box) the head sees by default: every proposal at 1, the
#: paper's single crop (:class:`~sarmission.perception.mitenet.MiteNet`; ``(1.0, 2.0)`` also crops
#: would-be detections at 2: docs/experiments.md, "the second look").
DEFAULT_CROP_SCALES = (1.0,)
#: Largest crop scale (multiple of the proposal box) the command line and mission files accept.
MAX_CROP_SCALE = 8.0


@dataclass
class Proposals:
    """TTM-RPN proposals in full-resolution pixels (``N`` rows; ``N`` may be 0).

    ``points`` are the response maxima (x, y) in full-resolution pixels before the forward shift,
    ``boxes`` the shifted square boxes ``[x1, y1, x2, y2]`` of side S, ``theta`` the motion
    direction in radians (0 = +x, counter-clockwise with y pointing up), ``polarity`` 1 for ON
    (L > 0 at the point) and 0 for OFF, ``source`` :data:`MOTION` or :data:`COLOUR` (which map
    the point is a maximum of; ``scores`` are that map's values). An empty ``source`` means all
    motion.
    """

    points: np.ndarray = field(default_factory=lambda: np.zeros((0, 2), np.float32))
    boxes: np.ndarray = field(default_factory=lambda: np.zeros((0, 4), np.float32))
    scores: np.ndarray = field(default_factory=lambda: np.zeros((0,), np.float32))
    theta: np.ndarray = field(default_factory=lambda: np.zeros((0,), np.float32))
    polarity: np.ndarray = field(default_factory=lambda: np.zeros((0,), np.float32))
    source: np.ndarray = field(default_factory=lambda: np.zeros((0,), np.uint8))

    def __len__(self) -> int:
        return int(self.boxes.shape[0])

    @property
    def from_colour(self) -> np.ndarray:
        """Boolean mask of the proposals that come from the chromatic anomaly map."""
        if self.source.shape[0] != len(self):
            return np.zeros(len(self), bool)
        return self.source == COLOUR


@dataclass
class Detections:
    """Head output for one frame: boxes ``[x1, y1, x2, y2]`` in full-resolution pixels."""

    boxes: np.ndarray = field(default_factory=lambda: np.zeros((0, 4), np.float32))
    scores: np.ndarray = field(default_factory=lambda: np.zeros((0,), np.float32))
    class_ids: np.ndarray = field(default_factory=lambda: np.zeros((0,), np.int64))

    def __len__(self) -> int:
        return int(self.boxes.shape[0])


@dataclass
class FrameResult:
    """Everything MITE-Net produced for one frame. ``camera_shift`` is how far the scene moved
    in the image since the previous frame (``(dx, dy)`` full-resolution pixels, content from
    ``x`` to ``x + shift``), as the motion front-end compensated it; None when not known."""

    timestamp: float
    detections: Detections
    proposals: Proposals
    motion: MotionMaps
    camera_shift: tuple[float, float] | None = None
