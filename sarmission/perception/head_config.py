"""The head's configuration and box decoding: what inference needs of the head without torch.

:class:`HeadConfig` travels in checkpoints and ONNX metadata; :func:`ltrb_to_boxes` turns the
decoded edge distances into frame boxes. The torch module itself is in
:mod:`sarmission.perception.head`, which re-exports both.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import numpy as np

DEFAULT_CLASSES: tuple[str, ...] = ("swimmer", "swimmer_with_life_jacket")


@dataclass(frozen=True)
class HeadConfig:
    """Architecture hyper-parameters of :class:`MiteHead` (stored in checkpoints and ONNX metadata).

    ``widths`` is ``(stem, backbone)`` channels, ``reg_bottleneck`` the channels of the regression
    bottleneck before the linear layer, ``crop_size`` the side S of the square input crops.
    ``motion_floor`` is part of the input's definition, not of the network: the temporal change
    below which the motion channel is not stretched to full scale
    (:func:`~sarmission.perception.crops.enhanced_response`; 0 for heads trained without one).
    ``crop_norm`` > 0 makes the head see each crop's colour relative to the crop itself: the
    crop's mean colour is taken away and what is left divided by the crop's spread, at least
    ``crop_norm`` (RGB in [0, 1]; a floor, so the noise of an empty crop is not stretched into
    structure; 1 centres only), so a sea or field of another tone or contrast than training's
    looks the same to it (0: raw colour, heads trained without).
    """

    classes: tuple[str, ...] = DEFAULT_CLASSES
    reg_max: int = 16
    widths: tuple[int, int] = (16, 24)
    reg_bottleneck: int = 4
    crop_size: int = 16
    in_channels: int = 4
    attention_reduction: int = 4
    cls_hidden: int = 32
    motion_floor: float = 0.0
    crop_norm: float = 0.0

    @property
    def num_classes(self) -> int:
        """Number of output classes."""
        return len(self.classes)

    def to_dict(self) -> dict:
        """JSON-friendly dict (tuples become lists)."""
        d = asdict(self)
        d["classes"] = list(self.classes)
        d["widths"] = list(self.widths)
        return d

    @classmethod
    def from_dict(cls, d: dict) -> HeadConfig:
        """Inverse of :meth:`to_dict`; unknown keys raise ``TypeError``, bad ones ``ValueError``."""
        d = dict(d)
        if "classes" in d:
            d["classes"] = tuple(str(c) for c in d["classes"])
        if "widths" in d:
            d["widths"] = tuple(int(w) for w in d["widths"])
        cfg = cls(**d)
        cfg.validate()
        return cfg

    def validate(self) -> None:
        """Raise ``ValueError`` when the configuration cannot build a head."""
        if not self.classes:
            raise ValueError("HeadConfig.classes must name at least one class")
        if self.reg_max < 1 or self.crop_size < 1 or self.in_channels < 1:
            raise ValueError(f"HeadConfig has non-positive sizes: {self}")
        if len(self.widths) != 2 or min(self.widths) < 1 or self.reg_bottleneck < 1:
            raise ValueError(f"HeadConfig.widths must be two positive ints, got {self.widths}")
        if not 0.0 <= self.motion_floor < 1.0:
            raise ValueError(f"HeadConfig.motion_floor must be in [0, 1), got {self.motion_floor}")
        if not 0.0 <= self.crop_norm <= 1.0:
            raise ValueError(f"HeadConfig.crop_norm must be in [0, 1], got {self.crop_norm}")


def ltrb_to_boxes(ltrb: np.ndarray, proposal_boxes: np.ndarray, crop_size: int = 16) -> np.ndarray:
    """Turn decoded distances (crop pixels) into full-resolution ``[x1, y1, x2, y2]`` boxes.

    The crop of proposal ``[bx1, by1, bx2, by2]`` is centred on the box centre; one crop pixel is
    ``(bx2 - bx1) / crop_size`` full-resolution pixels horizontally (likewise vertically).
    """
    ltrb = np.asarray(ltrb, dtype=np.float32).reshape(-1, 4)
    pb = np.asarray(proposal_boxes, dtype=np.float32).reshape(-1, 4)
    sx = (pb[:, 2] - pb[:, 0]) / crop_size
    sy = (pb[:, 3] - pb[:, 1]) / crop_size
    cx = (pb[:, 0] + pb[:, 2]) / 2
    cy = (pb[:, 1] + pb[:, 3]) / 2
    return np.stack(
        [cx - ltrb[:, 0] * sx, cy - ltrb[:, 1] * sy, cx + ltrb[:, 2] * sx, cy + ltrb[:, 3] * sy],
        axis=1,
    ).astype(np.float32)
