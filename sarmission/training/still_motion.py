"""Crops that look as a still person looks to a hovering camera: motion borrowed from background.

The head's fourth channel is the enhanced motion response E (:mod:`sarmission.perception.crops`),
normalised per crop to its own maximum. A person who does not move, seen from a camera that does
not move either, leaves no response of their own: E under them is the same normalised sensor
noise and compression flicker as anywhere on the ground. The training presets fly, so nearly
every positive carries some motion of its own (walking, or the parallax a moving camera leaves),
and a head can learn to want it. With ``share`` above 0, that share of a batch's crops (any
label) takes the E channel of a negative crop of the same batch drawn at random, so that the
class has to follow from what the crop looks like whenever the motion says nothing. RGB and the
box targets are unchanged; a batch without negatives is returned as it is.
"""

from __future__ import annotations

import numpy as np
import torch
from torch import Tensor

from sarmission.training.randomise import MOTION


def borrow_background_motion(
    crops: Tensor, labels: Tensor, share: float, rng: np.random.Generator
) -> Tensor:
    """``crops [N, 4, S, S]`` with ``share`` of them (drawn from ``rng``) given the E channel of
    a random negative of the batch (``labels`` below 0); a new tensor, the input is not modified."""
    if not 0.0 <= share <= 1.0:
        raise ValueError(f"share must be in [0, 1], got {share}")
    negatives = np.flatnonzero(labels.numpy() < 0)
    n = crops.shape[0]
    chosen = np.flatnonzero(rng.random(n) < share)
    if not len(negatives) or not len(chosen):
        return crops
    donors = negatives[rng.integers(0, len(negatives), size=len(chosen))]
    out = crops.clone()
    out[torch.from_numpy(chosen), MOTION] = crops[torch.from_numpy(donors), MOTION]
    return out
