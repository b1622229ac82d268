"""Training loop of the MITE-Net head on cached crops, with validation F2 and exact resume.

Per epoch the training crops are visited in a permutation drawn from
``numpy.random.default_rng([seed, epoch])`` (so a resumed run sees the same order), in batches of
``batch_size``. With ``augment`` each crop gets one of the 8 symmetries of the square (rotations
by 90 degrees and a mirror; a nadir view has no preferred orientation), drawn from the same
generator, and its ``l, t, r, b`` targets are permuted to match. With ``randomise`` naming
transforms, crop-level domain randomisation
(:func:`~sarmission.training.randomise.randomise_crops`) follows, drawn from
``numpy.random.default_rng([seed, epoch, 1])``. With ``texture_negatives`` above 0, that share
of a batch's size is added to it as negatives from a bank of procedural textures
(:mod:`sarmission.training.textures`, bank seeded by ``seed``), each with the motion channel and
scale of a training crop drawn at random (any label: a texture is nobody whatever moves there),
drawn from ``numpy.random.default_rng([seed, epoch, 2])``; they take the symmetries and the
randomisation as every crop does. With ``texture_positives`` above 0, that share of a batch's
positives has its surroundings replaced by a bank texture
(:func:`~sarmission.training.textures.paste_on_textures`), drawn from the same generator.
With ``still_share`` above 0, that share of a batch's crops then takes the motion channel of a
negative of the batch (:func:`~sarmission.training.still_motion.borrow_background_motion`,
drawn from ``numpy.random.default_rng([seed, epoch, 4])``): a still person under a hovering
camera has no motion of its own.
With ``keep_scores`` naming a trained head, that head's person probabilities on each batch's
crops (those not labelled one of the head's other classes) are taught too, weighted by
``kept_scores_weight`` (:mod:`sarmission.training.kept_scores`): a head learning boats and
buoys stays nearer the trained head's scores for people, on crops like the training set's.
The loss is :func:`~sarmission.training.losses.head_loss` (hard negatives mined per batch).
With ``rounding_consistency`` above 0, each batch also goes through the head as another
decoder's rounding would give it (:func:`~sarmission.training.consistency.rounding_perturbation`,
drawn from ``numpy.random.default_rng([seed, epoch, 3])``) and that weight times the squared gap
of the two class probabilities is added to the loss (:mod:`sarmission.training.consistency`).

Learning rate per optimiser step ``i`` of ``T`` (``W`` warm-up steps, one epoch at most)::

    lr_i = lr * min(1, (i + 1) / W) * (min_lr_ratio + (1 - min_lr_ratio)
                                       * (1 + cos(pi * i / T)) / 2)

With ``ema_decay > 0`` a copy of the head follows the trained weights as an exponential moving
average, updated after every optimiser step ``i`` (0-based) with the decay
``min(ema_decay, (1 + i) / (10 + i))`` (short runs still move it); BatchNorm running statistics
are averaged the same way. That copy, not the raw weights, is validated and written as the
checkpoint. It is off by default: with the default model's recipe the averaged head validates
more smoothly but finds no more and raises more false alarms (docs/experiments.md); it is there
for recipes whose validation F2 is too noisy to pick from.

Validation (after every epoch): the head runs on the validation crops (the real RPN proposals of
every validation frame after the warm-up, whatever ``frame_stride`` the training crops use, with
no background negatives and crop seed 0, so that runs of any seed share one validation cache: a
sparse validation set makes the F2 that selects the checkpoint swing by tens of percent between
epochs; no jittering), boxes are decoded with
:func:`~sarmission.perception.head.ltrb_to_boxes`, detections with score > ``score_threshold``
(score = largest class probability, class = its index) go through the inference NMS and those of
the person classes (:mod:`sarmission.class_roles`: a head may name boats too) are
scored against the person GT boxes of those frames with
:func:`sarmission.evaluation.box_metrics.evaluate_boxes` (class-aware; F2 of band ``all`` at
NWD 0.5, the threshold a detection must clear to count in the search metrics; the mean over NWD
0.5:0.95 is dominated by sub-pixel localisation of 16-px boxes and picked an epoch-1 head on the
simulator's maritime split). The checkpoint with the best validation F2 among the epochs from
``select_from`` on (the earlier epoch on ties) is written to ``out`` with
:func:`~sarmission.perception.runtime.save_head_checkpoint`; after every epoch the full state
(model, optimiser, weight average, epoch, best F2, history, torch RNG) goes to
``<out stem>.last.pt`` for ``resume``.

``select_from`` exists because the first epochs, still at the peak rate, can score a lucky F2
on a small validation set and pick a head that does worse on the search (docs/experiments.md).
"""

from __future__ import annotations

import copy
import math
import sys
import time
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np
import torch
from torch import Tensor

from sarmission.class_roles import person_class_ids
from sarmission.evaluation.box_metrics import evaluate_boxes
from sarmission.evaluation.matching import FrameBoxes
from sarmission.perception.head import HeadConfig, MiteHead, ltrb_to_boxes
from sarmission.perception.mitenet import nms_xyxy
from sarmission.perception.orientations import MIRROR_LTRB, ROT90_LTRB
from sarmission.perception.runtime import save_head_checkpoint
from sarmission.training.consistency import consistency_loss, rounding_perturbation
from sarmission.training.dataset import CropSet, CropSettings, load_crop_set
from sarmission.training.kept_scores import ScoreKeeper, load_keeper
from sarmission.training.losses import LossWeights, head_loss
from sarmission.training.randomise import Randomisation, randomise_crops
from sarmission.training.still_motion import borrow_background_motion
from sarmission.training.textures import paste_on_textures, texture_bank

STATE_FORMAT = "sarmission.train_state"
STATE_VERSION = 2
#: Config fields that may differ between a run and its resumption.
_RESUMABLE_CHANGES = ("resume", "progress", "num_threads", "cache_dir")
#: Texture crops in the bank that ``texture_negatives`` draws from.
TEXTURE_BANK_SIZE = 4096


@dataclass
class TrainConfig:
    """Everything a training run depends on.

    ``optimizer`` is ``"sgd"`` (Nesterov momentum) or ``"adamw"``; ``cache_dir`` ``None`` puts
    the crop caches in ``<out folder>/.crop_cache``; ``crops`` are the training crop settings
    (validation uses the same without jittering, on every frame).
    """

    train: Path
    val: Path
    out: Path
    epochs: int = 30
    batch_size: int = 64
    #: Peak SGD rate. 0.05 left the validation F2 of the default recipe at 0.13-0.21 from epoch
    #: to epoch; 0.02 gives 0.19-0.32 (maritime training presets, maritime_val).
    lr: float = 0.02
    optimizer: str = "sgd"
    momentum: float = 0.9
    weight_decay: float = 5e-4
    min_lr_ratio: float = 0.01
    #: Decay of the weight average that is validated and saved (0 = the raw weights).
    ema_decay: float = 0.0
    seed: int = 0
    augment: bool = True
    randomise: Randomisation = field(default_factory=Randomisation)
    #: Procedural texture negatives added to each batch, as a share of the batch size (0: none).
    texture_negatives: float = 0.0
    #: Share of the positives put on a procedural texture (0: none).
    texture_positives: float = 0.0
    #: Weight of the rounding-consistency term (0: none; :mod:`sarmission.training.consistency`).
    rounding_consistency: float = 0.0
    #: The head sees each crop's colour relative to the crop, its spread floored at this
    #: (:class:`HeadConfig` ``crop_norm``; 0: raw colour).
    crop_norm: float = 0.0
    #: Share of the crops given the motion channel of a negative of their batch (0: none;
    #: :mod:`sarmission.training.still_motion`).
    still_share: float = 0.0
    crops: CropSettings = field(default_factory=CropSettings)
    loss: LossWeights = field(default_factory=LossWeights)
    score_threshold: float = 0.5
    nms_iou: float = 0.5
    #: First epoch (1-based) whose head may be chosen as the best checkpoint.
    select_from: int = 1
    cache_dir: Path | None = None
    #: Start from this trained head's weights (``"default"``: the shipped head; None: fresh);
    #: :mod:`sarmission.training.init_weights`.
    init: str | None = None
    #: New class -> the class of the ``init`` head its weights start from.
    init_classes: dict[str, str] = field(default_factory=dict)
    #: Keep this trained head's person scores (``"default"``, a shipped head's name or a .pt;
    #: None: off); :mod:`sarmission.training.kept_scores`.
    keep_scores: str | None = None
    #: Weight of the kept-scores term beside the head's own loss.
    kept_scores_weight: float = 4.0
    resume: bool = False
    num_threads: int = 2
    progress: bool = True

    def validate(self) -> None:
        """Raise ``ValueError`` for impossible settings."""
        if self.epochs < 1 or self.batch_size < 1:
            raise ValueError("epochs and batch_size must be at least 1")
        if Path(self.out).is_dir():  # found before the crops are cut, not after training
            raise ValueError(f"out {self.out} is a folder; give the head file to write")
        if not 1 <= self.select_from <= self.epochs:
            raise ValueError(
                f"select_from must be in [1, epochs = {self.epochs}], got {self.select_from}"
            )
        if not (self.lr > 0 and math.isfinite(self.lr)):
            raise ValueError(f"lr must be a positive number, got {self.lr}")
        if self.optimizer not in ("sgd", "adamw"):
            raise ValueError(f"optimizer must be 'sgd' or 'adamw', got {self.optimizer!r}")
        if not 0.0 <= self.min_lr_ratio <= 1.0:
            raise ValueError(f"min_lr_ratio must be in [0, 1], got {self.min_lr_ratio}")
        if not 0.0 <= self.texture_negatives <= 4.0:
            raise ValueError(f"texture_negatives must be in [0, 4], got {self.texture_negatives}")
        if not 0.0 <= self.texture_positives <= 1.0:
            raise ValueError(f"texture_positives must be in [0, 1], got {self.texture_positives}")
        if not 0.0 <= self.rounding_consistency <= 100.0:
            raise ValueError(
                f"rounding_consistency must be in [0, 100], got {self.rounding_consistency}"
            )
        if not 0.0 <= self.crop_norm <= 1.0:
            raise ValueError(f"crop_norm must be in [0, 1], got {self.crop_norm}")
        if not 0.0 <= self.still_share <= 1.0:
            raise ValueError(f"still_share must be in [0, 1], got {self.still_share}")
        if not 0.0 < self.kept_scores_weight <= 100.0:
            raise ValueError(
                f"kept_scores_weight must be in (0, 100], got {self.kept_scores_weight}"
            )
        if not 0.0 <= self.ema_decay < 1.0:
            raise ValueError(f"ema_decay must be in [0, 1), got {self.ema_decay}")
        self.randomise.validate()
        self.crops.validate()

    def fingerprint(self) -> dict:
        """The settings a resumed run must share with the interrupted one (JSON-friendly)."""
        d = asdict(self)
        for key in _RESUMABLE_CHANGES:
            d.pop(key)
        optional = (
            "texture_negatives",
            "texture_positives",
            "rounding_consistency",
            "crop_norm",
            "still_share",
            "keep_scores",
        )
        for key in optional:
            if not d[key]:
                d.pop(key)  # states written before the setting existed still resume
        if "keep_scores" not in d:
            d.pop("kept_scores_weight")
        d["crops"] = self.crops.to_dict()
        if not d["crops"]["motion_floor"]:
            d["crops"].pop("motion_floor")  # likewise
        d["randomise"] = {
            "transforms": list(self.randomise.transforms),
            "probability": self.randomise.probability,
        }
        return {k: (str(v) if isinstance(v, Path) else v) for k, v in d.items()}


@dataclass
class TrainResult:
    """Outcome of :func:`train`. ``history`` has one dict per epoch (loss terms, F2, lr, time)."""

    checkpoint: Path
    state: Path
    best_f2: float
    best_epoch: int
    epochs_run: int
    history: list[dict]
    train_crops: int
    val_crops: int


def state_path(out: str | Path) -> Path:
    """Resume-state file of a run writing ``out``: ``<out stem>.last.pt`` beside it."""
    out = Path(out)
    return out.with_name(out.stem + ".last.pt")


def lr_at(step: int, total: int, warmup: int, lr: float, min_lr_ratio: float) -> float:
    """Warm-up then cosine learning rate (formula in the module docstring)."""
    warm = min(1.0, (step + 1) / max(warmup, 1))
    cosine = (1.0 + math.cos(math.pi * step / max(total, 1))) / 2.0
    return lr * warm * (min_lr_ratio + (1.0 - min_lr_ratio) * cosine)


class WeightAverage:
    """Exponential moving average of a head's weights and buffers (module docstring)."""

    def __init__(self, model: MiteHead, decay: float) -> None:
        self.decay = decay
        self.updates = 0
        self.model = copy.deepcopy(model).eval()
        for parameter in self.model.parameters():
            parameter.requires_grad_(False)

    @torch.no_grad()
    def update(self, model: MiteHead) -> None:
        """Fold the current weights of ``model`` into the average."""
        decay = min(self.decay, (1 + self.updates) / (10 + self.updates))
        current = model.state_dict()
        for name, average in self.model.state_dict().items():
            if average.is_floating_point():
                average.mul_(decay).add_(current[name], alpha=1.0 - decay)
            else:
                average.copy_(current[name])
        self.updates += 1

    def state_dict(self) -> dict:
        """The averaged weights and the update count, for the resume state."""
        return {"model": self.model.state_dict(), "updates": self.updates}

    def load_state_dict(self, state: dict) -> None:
        """Restore what :meth:`state_dict` returned."""
        self.model.load_state_dict(state["model"])
        self.updates = int(state["updates"])


def dihedral(
    crops: Tensor, ltrb: Tensor, scale: Tensor, ops: Tensor
) -> tuple[Tensor, Tensor, Tensor]:
    """Apply symmetry ``ops[i]`` in 0..7 (``k = op % 4`` quarter turns, then a mirror when
    ``op >= 4``) to crop ``i`` ``[N, C, S, S]``, its ``l, t, r, b`` ``[N, 4]`` and its
    ``(sx, sy)`` scale ``[N, 2]`` (swapped by odd turns).
    """
    crops, ltrb, scale = crops.clone(), ltrb.clone(), scale.clone()
    for op in torch.unique(ops).tolist():
        idx = torch.nonzero(ops == op).flatten()
        c, t, s = crops[idx], ltrb[idx], scale[idx]
        for _ in range(op % 4):
            c, t, s = torch.rot90(c, 1, dims=(2, 3)), t[:, ROT90_LTRB], s[:, [1, 0]]
        if op >= 4:
            c, t = torch.flip(c, dims=(3,)), t[:, MIRROR_LTRB]
        crops[idx], ltrb[idx], scale[idx] = c, t, s
    return crops, ltrb, scale


def _optimizer(model: MiteHead, config: TrainConfig) -> torch.optim.Optimizer:
    decay = [p for p in model.parameters() if p.ndim > 1]
    no_decay = [p for p in model.parameters() if p.ndim <= 1]
    groups = [
        {"params": decay, "weight_decay": config.weight_decay},
        {"params": no_decay, "weight_decay": 0.0},
    ]
    if config.optimizer == "sgd":
        return torch.optim.SGD(groups, lr=config.lr, momentum=config.momentum, nesterov=True)
    return torch.optim.AdamW(groups, lr=config.lr)


#: NWD threshold of the validation F2 that selects the checkpoint (the SAR match threshold).
SELECTION_NWD = (0.5,)


@torch.no_grad()
def validate_f2(
    model: MiteHead,
    val: CropSet,
    score_threshold: float = 0.5,
    nms_iou: float | None = 0.5,
    chunk: int = 1024,
) -> dict[str, float]:
    """F2, precision and recall of the head on validation crops (module docstring)."""
    model.eval()
    logits, ltrb = [], []
    for start in range(0, len(val), chunk):
        lo, lt = model(val.crops[start : start + chunk].float())
        logits.append(lo)
        ltrb.append(lt)
    probs = torch.sigmoid(torch.cat(logits)).numpy() if logits else np.zeros((0, 1))
    scores, classes = probs.max(axis=1), probs.argmax(axis=1)
    boxes = ltrb_to_boxes(
        torch.cat(ltrb).numpy() if ltrb else np.zeros((0, 4)),
        val.boxes.numpy(),
        val.crops.shape[-1],
    )
    image_ids = val.image_ids.numpy()
    detections, truth = {}, {}
    gt_images, gt_boxes = val.gt_image_ids.numpy(), val.gt_boxes.numpy()
    gt_classes = val.gt_classes.numpy()
    people = person_class_ids(model.config.classes)
    person_detection, person_gt = np.isin(classes, people), np.isin(gt_classes, people)
    for image_id in val.frame_ids.tolist():
        keep = np.flatnonzero(
            (image_ids == image_id) & (scores > score_threshold) & person_detection
        )
        if nms_iou is not None and keep.size > 1:
            keep = keep[nms_xyxy(boxes[keep], scores[keep], nms_iou)]
        detections[image_id] = FrameBoxes.of(boxes[keep], scores[keep], classes[keep])
        g = (gt_images == image_id) & person_gt
        truth[image_id] = FrameBoxes.of(gt_boxes[g], class_ids=gt_classes[g])
    band = evaluate_boxes(
        truth, detections, nwd_thresholds=SELECTION_NWD, score_thr=score_threshold
    ).bands["all"]
    return {"f2": band.f2 or 0.0, "precision": band.precision or 0.0, "recall": band.recall or 0.0}


def _load_state(
    config: TrainConfig,
    model: MiteHead,
    optimizer: torch.optim.Optimizer,
    average: WeightAverage | None,
) -> dict:
    path = state_path(config.out)
    if not path.is_file():
        raise FileNotFoundError(f"cannot resume: no training state at {path}")
    try:
        state = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as exc:  # noqa: BLE001 - torch raises anything on a truncated file
        raise ValueError(
            f"cannot resume: {path} is not readable ({type(exc).__name__}: "
            f"{str(exc).splitlines()[0][:120] if str(exc) else ''}); delete it to start afresh"
        ) from None
    if not isinstance(state, dict) or state.get("format") != STATE_FORMAT:
        raise ValueError(f"cannot resume: {path} is not a sarmission training state")
    if state.get("version") != STATE_VERSION:
        raise ValueError(
            f"cannot resume: {path} has state version {state.get('version')!r}, "
            f"this build reads {STATE_VERSION}"
        )
    saved, now = state["config"], config.fingerprint()
    changed = sorted(k for k in set(saved) | set(now) if saved.get(k) != now.get(k))
    if changed:
        raise ValueError(
            f"cannot resume {path}: settings differ from the interrupted run ({', '.join(changed)})"
        )
    model.load_state_dict(state["model"])
    optimizer.load_state_dict(state["optimizer"])
    if average is not None:
        average.load_state_dict(state["average"])
    torch.set_rng_state(state["torch_rng"])
    return state


def _train_epoch(
    model: MiteHead,
    optimizer: torch.optim.Optimizer,
    data: CropSet,
    config: TrainConfig,
    epoch: int,
    bar,
    average: WeightAverage | None = None,
    textures: Tensor | None = None,
    keeper: ScoreKeeper | None = None,
) -> dict[str, float]:
    """One pass over the training crops; mean loss terms per batch. ``textures``: the bank
    texture negatives are drawn from; ``keeper``: the head whose person scores are kept
    (module docstring)."""
    model.train()
    n = len(data)
    rng = np.random.default_rng([config.seed, epoch])
    order = torch.from_numpy(rng.permutation(n))
    ops = torch.from_numpy(rng.integers(0, 8, size=n))
    randomising = np.random.default_rng([config.seed, epoch, 1])
    texturing = np.random.default_rng([config.seed, epoch, 2])
    rounding = np.random.default_rng([config.seed, epoch, 3])
    stilling = np.random.default_rng([config.seed, epoch, 4])
    steps = math.ceil(n / config.batch_size)
    scale_all = data.scale
    sums = dict.fromkeys(("loss", "cls", "nwd", "dfl", "rounding", "kept"), 0.0)
    for b in range(steps):
        idx = order[b * config.batch_size : (b + 1) * config.batch_size]
        lr = lr_at(epoch * steps + b, config.epochs * steps, steps, config.lr, config.min_lr_ratio)
        for group in optimizer.param_groups:
            group["lr"] = lr
        crops, target, scale = data.crops[idx].float(), data.target_ltrb[idx], scale_all[idx]
        labels, symmetry = data.labels[idx], ops[idx]
        if textures is not None:
            extra = round(config.texture_negatives * len(idx))
            crops, target, scale, labels, symmetry = with_texture_negatives(
                (crops, target, scale, labels, symmetry),
                textures,
                (data.crops, scale_all),
                extra,
                texturing,
            )
            if config.texture_positives > 0:
                crops = with_positives_on_textures(
                    crops, labels, textures, config.texture_positives, texturing
                )
        if config.augment:
            crops, target, scale = dihedral(crops, target, scale, symmetry)
        if config.randomise.transforms:
            crops, target = randomise_crops(crops, target, labels, config.randomise, randomising)
        if config.still_share > 0:
            crops = borrow_background_motion(crops, labels, config.still_share, stilling)
        if config.rounding_consistency > 0:
            both = torch.cat([crops, rounding_perturbation(crops, rounding)])
            all_logits, all_bins, all_ltrb = model.forward_with_bins(both)
            m = len(crops)
            cls_logits, bins, ltrb = all_logits[:m], all_bins[:m], all_ltrb[:m]
            steady = consistency_loss(cls_logits, all_logits[m:])
        else:
            cls_logits, bins, ltrb = model.forward_with_bins(crops)
            steady = None
        terms = head_loss(cls_logits, bins, ltrb, labels, target, scale, config.loss)
        total = terms.total
        if steady is not None:
            total = total + config.rounding_consistency * steady
            sums["rounding"] += float(steady.detach())
        if keeper is not None:
            kept = keeper.loss(cls_logits, crops, labels)
            total = total + config.kept_scores_weight * kept
            sums["kept"] += float(kept.detach())
        optimizer.zero_grad(set_to_none=True)
        total.backward()
        optimizer.step()
        if average is not None:
            average.update(model)
        for key, value in (
            ("loss", total.detach()),
            ("cls", terms.cls),
            ("nwd", terms.nwd),
            ("dfl", terms.dfl),
        ):
            sums[key] += float(value)
        bar.update(1)
        bar.set_postfix(epoch=epoch + 1, loss=f"{sums['loss'] / (b + 1):.3f}")
    return {k: v / max(steps, 1) for k, v in sums.items()} | {"lr": lr}


def with_positives_on_textures(
    crops: Tensor, labels: Tensor, textures: Tensor, share: float, rng: np.random.Generator
) -> Tensor:
    """``crops`` with a random ``share`` of the positives' surroundings replaced by textures
    (:func:`~sarmission.training.textures.paste_on_textures`); motion channel untouched."""
    chosen = np.flatnonzero((labels.numpy() >= 0) & (rng.random(len(labels)) < share))
    if not len(chosen):
        return crops
    picks = rng.integers(0, len(textures), size=len(chosen))
    out = crops.clone()
    rgb = crops[chosen, :3].numpy()
    out[chosen, :3] = torch.from_numpy(
        paste_on_textures(rgb, textures[picks].numpy()).astype(np.float32)
    )
    return out


def with_texture_negatives(
    batch: tuple[Tensor, Tensor, Tensor, Tensor, Tensor],
    textures: Tensor,
    donors: tuple[Tensor, Tensor],
    count: int,
    rng: np.random.Generator,
) -> tuple[Tensor, Tensor, Tensor, Tensor, Tensor]:
    """``batch`` (crops, targets, scales, labels, symmetries) with ``count`` texture negatives
    appended: RGB from ``textures``, motion channel and scale from random crops of ``donors``
    (all training crops ``[N, 4, S, S]`` and their scales ``[N, 2]``)."""
    crops, target, scale, labels, symmetry = batch
    if count <= 0:
        return batch
    donor_crops, donor_scale = donors
    picks = torch.from_numpy(rng.integers(0, len(textures), size=count))
    chosen = torch.from_numpy(rng.integers(0, len(donor_crops), size=count))
    added = torch.cat([textures[picks], donor_crops[chosen, 3:].float()], dim=1)
    return (
        torch.cat([crops, added]),
        torch.cat([target, torch.zeros(count, 4, dtype=target.dtype)]),
        torch.cat([scale, donor_scale[chosen]]),
        torch.cat([labels, torch.full((count,), -1, dtype=labels.dtype)]),
        torch.cat([symmetry, torch.from_numpy(rng.integers(0, 8, size=count))]),
    )


def validation_settings(crops: CropSettings) -> CropSettings:
    """The crops validation scores: those inference classifies first, the RPN's on every frame,
    with none of the training-only samples (jittered GT, background, object and context crops)."""
    return replace(
        crops,
        jitters_per_gt=0,
        background_negatives=0,
        object_negatives=0,
        object_context=0,
        frame_stride=1,
        seed=0,
    )


def train(config: TrainConfig) -> TrainResult:
    """Train the head (module docstring); returns where the best checkpoint went and the history.

    Raises ``OSError`` for missing files and ``ValueError`` for bad settings or annotations.
    """
    from tqdm import tqdm

    config.validate()
    torch.set_num_threads(max(1, config.num_threads))
    cache_dir = Path(config.cache_dir) if config.cache_dir else config.out.parent / ".crop_cache"
    keeper = None  # read before the crops are cut: a bad file fails at once
    if config.keep_scores is not None:
        keeper = load_keeper(config.keep_scores, tuple(config.crops.classes))
    t0 = time.perf_counter()
    train_set, _ = load_crop_set(
        config.train, config.crops, cache_dir, config.progress, "train crops"
    )
    val_set, _ = load_crop_set(
        config.val, validation_settings(config.crops), cache_dir, config.progress, "val crops"
    )
    if not (train_set.labels >= 0).any():
        raise ValueError(
            f"{config.train}: no positive training crop (no target GT boxes in the sampled frames)"
        )
    people = person_class_ids(tuple(config.crops.classes))
    if not np.isin(val_set.gt_classes.numpy(), people).any():  # F2 0 at every epoch
        raise ValueError(
            f"{config.val}: no person box in the validation frames (or no person class among "
            f"{', '.join(config.crops.classes)}): the validation F2 could not choose an epoch"
        )
    print(
        f"train: {train_set.summary()}\nval: {val_set.summary()} "
        f"({time.perf_counter() - t0:.1f} s)",
        file=sys.stderr,
    )

    torch.manual_seed(config.seed)
    model = MiteHead(
        HeadConfig(
            classes=tuple(config.crops.classes),
            motion_floor=config.crops.motion_floor,
            crop_norm=config.crop_norm,
        )
    )
    optimizer = _optimizer(model, config)
    average = WeightAverage(model, config.ema_decay) if config.ema_decay > 0 else None
    evaluated = average.model if average is not None else model
    start, best_f2, best_epoch, history = 0, -1.0, 0, []
    if config.init is not None and not config.resume:
        from sarmission.training.init_weights import initialise_from

        report = initialise_from(model, config.init, config.init_classes)
        print(report.summary(), file=sys.stderr)
    if keeper is not None:
        keeper.check_fits(model, config.keep_scores)
    if config.resume:
        state = _load_state(config, model, optimizer, average)
        start, best_f2, best_epoch = state["epoch"], state["best_f2"], state["best_epoch"]
        history = list(state["history"])
    steps = math.ceil(len(train_set) / config.batch_size)
    textures = None
    if config.texture_negatives > 0 or config.texture_positives > 0:
        size = train_set.crops.shape[-1]
        textures = torch.from_numpy(texture_bank(TEXTURE_BANK_SIZE, size, config.seed))
    with tqdm(
        total=steps * (config.epochs - start),
        unit="batch",
        desc="train",
        file=sys.stderr,
        disable=not config.progress,
    ) as bar:
        for epoch in range(start, config.epochs):
            t_epoch = time.perf_counter()
            record = _train_epoch(
                model, optimizer, train_set, config, epoch, bar, average, textures, keeper
            )
            if not math.isfinite(record["loss"]):  # a head of NaN weights detects nothing
                kept = f"; {config.out} holds epoch {best_epoch}" if best_epoch else ""
                raise ValueError(
                    f"training diverged in epoch {epoch + 1} (loss {record['loss']}): lower "
                    f"--lr (now {config.lr:g}){kept}"
                )
            record |= validate_f2(evaluated, val_set, config.score_threshold, config.nms_iou)
            record |= {"epoch": epoch + 1, "seconds": time.perf_counter() - t_epoch}
            history.append(record)
            if epoch + 1 >= config.select_from and record["f2"] > best_f2:
                best_f2, best_epoch = record["f2"], epoch + 1
                save_head_checkpoint(evaluated, config.out)
            bar.write(
                f"epoch {epoch + 1}/{config.epochs}: loss {record['loss']:.4f} "
                f"(cls {record['cls']:.3f} nwd {record['nwd']:.3f} dfl {record['dfl']:.3f}"
                + (f" rounding {record['rounding']:.4f}" if config.rounding_consistency else "")
                + (f" kept {record['kept']:.4f}" if keeper is not None else "")
                + f") val F2 {record['f2']:.4f} P {record['precision']:.3f} "
                f"R {record['recall']:.3f} best {best_f2:.4f}@{best_epoch}"
            )
            _save_state(config, model, optimizer, average, epoch + 1, best_f2, best_epoch, history)
    return TrainResult(
        config.out,
        state_path(config.out),
        best_f2,
        best_epoch,
        config.epochs - start,
        history,
        len(train_set),
        len(val_set),
    )


def _save_state(
    config: TrainConfig,
    model: MiteHead,
    optimizer: torch.optim.Optimizer,
    average: WeightAverage | None,
    epoch: int,
    best_f2: float,
    best_epoch: int,
    history: list[dict],
) -> None:
    path = state_path(config.out)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp")
    torch.save(
        {
            "format": STATE_FORMAT,
            "version": STATE_VERSION,
            "epoch": epoch,
            "model": model.state_dict(),
            "optimizer": optimizer.state_dict(),
            "average": average.state_dict() if average is not None else None,
            "best_f2": best_f2,
            "best_epoch": best_epoch,
            "history": history,
            "torch_rng": torch.get_rng_state(),
            "config": config.fingerprint(),
        },
        tmp,
    )
    tmp.replace(path)
