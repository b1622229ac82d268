"""Keep a trained head's person scores while a new head learns other classes.

A head that learns boats, buoys and life rings as classes of their own (``--classes
maritime``) also moves its person scores: on the simulator's flights it scores people higher
than the shipped head, on footage it never saw lower, so no one confirmation threshold serves
both (docs/mooring_buoys.md). Here the trained head (the *keeper*, frozen) teaches the new one
its person probabilities on every crop that is not one of the new head's non-person classes
(learning without forgetting), so that only where the labels say "buoy" or "boat" does it
learn otherwise. That holds on crops like the training set's; on footage unlike it the new
head's scores for people may still move (docs/mooring_buoys.md, 2026-12-02).

For a batch's crops ``i`` outside those classes and the person classes ``c`` both heads name::

    L_kept = mean_{i, c} BCE(z_ic, sigmoid(k_ic))

with ``z`` the new head's logits and ``k`` the keeper's on the same (augmented) crops.
``TrainConfig.kept_scores_weight`` weights it beside the head's own loss. The new head
learns in batch statistics and the keeper answers in its running ones, as it runs in the
mission.
"""

from __future__ import annotations

from pathlib import Path

import torch
import torch.nn.functional as F
from torch import Tensor

from sarmission.class_roles import normalise_class, person_class_ids
from sarmission.perception.head import MiteHead
from sarmission.training.init_weights import architecture_differences, init_path


class ScoreKeeper:
    """The frozen keeper head and which of its classes the new head's person classes are."""

    def __init__(self, keeper: MiteHead, classes: tuple[str, ...], source: Path | str) -> None:
        own = person_class_ids(classes).tolist()
        theirs = {normalise_class(c): i for i, c in enumerate(keeper.config.classes)}
        missing = [classes[i] for i in own if normalise_class(classes[i]) not in theirs]
        if missing:
            raise ValueError(
                f"--keep-scores {source}: it names no class {', '.join(missing)} "
                f"(it has {', '.join(keeper.config.classes)})"
            )
        self.keeper = keeper.eval()
        for p in self.keeper.parameters():
            p.requires_grad_(False)
        self.student_ids = torch.as_tensor(own, dtype=torch.long)
        self.keeper_ids = torch.as_tensor(
            [theirs[normalise_class(classes[i])] for i in own], dtype=torch.long
        )
        #: Label ids that are classes of the new head's own other than people.
        self.other_ids = torch.as_tensor(
            [i for i in range(len(classes)) if i not in own], dtype=torch.long
        )

    def check_fits(self, model: MiteHead, source: Path | str) -> None:
        """Raise ``ValueError`` when ``model`` cuts or sees crops otherwise than the keeper."""
        differ = architecture_differences(model.config, self.keeper.config)
        if differ:
            raise ValueError(
                f"--keep-scores {source}: it differs from the head being trained in "
                + ", ".join(differ)
            )

    def loss(self, logits: Tensor, crops: Tensor, labels: Tensor) -> Tensor:
        """``L_kept`` (module docstring) of the new head's ``logits`` ``[N, C]`` on ``crops``
        with ``labels`` ``[N]`` (-1 for nothing); 0 when every crop is of another class."""
        kept = ~torch.isin(labels, self.other_ids)
        if not bool(kept.any()):
            return logits.sum() * 0.0
        with torch.no_grad():
            keeper_logits, _ = self.keeper(crops[kept])
            target = torch.sigmoid(keeper_logits[:, self.keeper_ids])
        return F.binary_cross_entropy_with_logits(logits[kept][:, self.student_ids], target)


def load_keeper(source: str | Path, classes: tuple[str, ...]) -> ScoreKeeper:
    """The :class:`ScoreKeeper` of the checkpoint ``source`` (``default``, ``maritime``,
    ``land`` or a ``.pt`` file) for a head naming ``classes``.

    Raises :class:`~sarmission.perception.runtime.ModelLoadError` for an unreadable file and
    ``ValueError`` when it does not name the new head's person classes."""
    from sarmission.perception.runtime import load_head_checkpoint

    path = init_path(source, "--keep-scores")
    return ScoreKeeper(load_head_checkpoint(path), classes, path)
