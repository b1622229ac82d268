"""MITE-Net cascade: vSTMD → TTM-RPN → motion-enhanced crops → head → detections (paper section 3).

One :class:`MiteNet` per video stream; frames go in order through :meth:`MiteNet.process`, which
keeps the vSTMD state between frames (:meth:`MiteNet.reset` starts a new stream).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from pathlib import Path

import numpy as np

from sarmission.perception import extent
from sarmission.perception.chroma import (
    CHROMA_SCALE,
    chroma_applies,
    chroma_flops,
    chroma_if_wanted,
)
from sarmission.perception.crops import CROP_SIZE, crop_flops, motion_enhanced_crops
from sarmission.perception.extent import fit_boxes
from sarmission.perception.head_config import HeadConfig, ltrb_to_boxes
from sarmission.perception.orientations import (
    check_orientations,
    ltrb_from_orientation,
    oriented_crops,
)
from sarmission.perception.pyramid import half_resolution
from sarmission.perception.rpn import TTMRPN
from sarmission.perception.runtime import (
    HeadRuntime,
    OnnxHeadRuntime,
    RuntimeName,
    load_head_runtime,
)
from sarmission.perception.types import (
    DEFAULT_COLOUR_SHARE,
    DEFAULT_CROP_SCALES,
    Detections,
    FrameResult,
    MotionMaps,
    Proposals,
)
from sarmission.perception.vstmd import VSTMD
from sarmission.yuv import YuvImage

STAGES = ("vstmd", "colour", "rpn", "crops", "head", "fit")
#: With ``recentre``: how far (full-resolution pixels) the head's box centre must lie from the
#: crop's, and how high the first crop must score, for a proposal to be cropped again.
RECENTRE_MIN_SHIFT_PX = 2.0
RECENTRE_MIN_SCORE = 0.1
#: With ``fit_boxes``: the longest fitted box, as a multiple of the proposal side S (64 px at
#: S 16). Longer than a person drawn at the largest scale the head sees (~60 px), short of a
#: boat; a longer extent keeps the head's box.
FIT_MAX_SIDE_S = 4.0
#: With ``fit_boxes``: the lowest score whose box is fitted. A detection scored lower never
#: counts towards a lock (the mission's and the evaluation's m-of-k take 0.5), so its box is
#: not worth the half millisecond a fit costs.
FIT_MIN_SCORE = 0.5
#: With ``fit_boxes``: at most this many boxes are fitted per frame, the best-scored first: the
#: fitting's cost stays bounded on a frame full of confident detections.
FIT_MAX_PER_FRAME = 8
#: With a person's expected size (``process(person_px=...)``): the largest factor a crop grows
#: by, as a multiple of its side at the survey's ranges (a person of 8 S, 128 px at S 16, is
#: seen from a few metres; a wider crop would hold the drone's own surroundings).
MAX_RANGE_FACTOR = 8.0


def _sigmoid(logits: np.ndarray) -> np.ndarray:
    """Class probabilities (float64) of the head's logits."""
    return 1.0 / (1.0 + np.exp(-logits.astype(np.float64)))


def _shifted(logits: np.ndarray, shift: np.ndarray | None) -> np.ndarray:
    """``logits`` ``[N, C]`` each row lowered by its ``shift`` ``[N]`` (none: unchanged)."""
    if shift is None or not np.any(shift):
        return logits
    return logits.astype(np.float64) - np.asarray(shift, dtype=np.float64).reshape(-1, 1)


def scaled_boxes(boxes: np.ndarray, scale: float | np.ndarray) -> np.ndarray:
    """``xyxy`` boxes scaled by ``scale`` (one number, or one per box) about their centres
    (float32; a copy, exact at 1)."""
    if np.all(np.asarray(scale) == 1.0):
        return np.array(boxes, dtype=np.float32)
    centre = (boxes[:, :2] + boxes[:, 2:]) / 2
    half = (boxes[:, 2:] - boxes[:, :2]) / 2 * np.asarray(scale, dtype=np.float64).reshape(-1, 1)
    return np.concatenate([centre - half, centre + half], axis=1).astype(np.float32)


def build_head_runtime(
    model: str | Path | None = None,
    runtime: RuntimeName = "torch",
    intra_op_threads: int | None = None,
) -> HeadRuntime:
    """Head runtime from a model file; with ``model=None`` the shipped default model, or, when the
    package has none, an untrained head with fixed seed-0 weights (for timing and FLOP counts).
    """
    if model is not None:
        return load_head_runtime(model, runtime, intra_op_threads)
    from sarmission.models import DEFAULT_ONNX_MODEL, DEFAULT_TORCH_MODEL

    shipped = DEFAULT_ONNX_MODEL if runtime == "onnx" else DEFAULT_TORCH_MODEL
    if shipped.is_file():
        return load_head_runtime(shipped, runtime, intra_op_threads)
    if DEFAULT_TORCH_MODEL.is_file():
        return load_head_runtime(DEFAULT_TORCH_MODEL, runtime, intra_op_threads)
    import torch

    from sarmission.perception.head import MiteHead
    from sarmission.perception.runtime import TorchHeadRuntime

    with torch.random.fork_rng(devices=[]):
        torch.manual_seed(0)
        head = MiteHead().eval()
    if runtime == "onnx":
        from sarmission.perception.export import head_onnx_bytes

        return OnnxHeadRuntime(head_onnx_bytes(head), intra_op_threads, name="<untrained head>")
    return TorchHeadRuntime(head)


def nms_xyxy(boxes: np.ndarray, scores: np.ndarray, iou_threshold: float) -> np.ndarray:
    """Greedy IoU non-maximum suppression; indices of the kept boxes, best score first.

    The pairwise IoU matrix is computed once; the greedy pass then only reads its rows (cheaper
    than a per-box loop of array operations).
    """
    order = np.argsort(-scores, kind="stable")
    area = np.maximum(boxes[:, 2] - boxes[:, 0], 0) * np.maximum(boxes[:, 3] - boxes[:, 1], 0)
    iw = np.maximum(
        np.minimum(boxes[:, None, 2], boxes[None, :, 2])
        - np.maximum(boxes[:, None, 0], boxes[None, :, 0]),
        0,
    )
    ih = np.maximum(
        np.minimum(boxes[:, None, 3], boxes[None, :, 3])
        - np.maximum(boxes[:, None, 1], boxes[None, :, 1]),
        0,
    )
    inter = iw * ih
    overlaps = inter / np.maximum(area[:, None] + area[None, :] - inter, 1e-9) > iou_threshold
    suppressed = np.zeros(len(order), dtype=bool)
    keep: list[int] = []
    for i in order.tolist():
        if not suppressed[i]:
            keep.append(i)
            suppressed |= overlaps[i]
    return np.asarray(keep, dtype=np.int64)


class MiteNet:
    """The MITE-Net detector for one video stream.

    Args:
        head_runtime: a :class:`~sarmission.perception.runtime.HeadRuntime` (torch or onnx).
        ds: vSTMD down-sampling factor (power-saving mode; 1 = full resolution).
        topn: proposals per frame (N).
        target_size: expected target size in full-resolution pixels (vSTMD size-selective
            kernel); None keeps the vSTMD default.
        box_size: proposal box side S in full-resolution pixels.
        score_threshold: minimum class probability (sigmoid of the logit) of a kept detection.
        classes: expected class names; must equal the head's when given.
        nms_iou: IoU above which the lower-scored of two detections is dropped (None: no NMS).
        ego_motion: "estimate" compensates the camera's own motion in vSTMD (moving drone);
            "none" assumes a still camera and saves the estimate's cost.
        colour_share: share of the N proposals taken from the chromatic anomaly map
            (:mod:`~sarmission.perception.chroma`); 0 = motion proposals only (the paper's RPN).
        crop_scales: crop sides as multiples of S, each a box of ``scale * S`` around the
            proposal's centre resampled to the head's 16 x 16 input. Every proposal is cropped
            at the first scale; those whose first crop scores at least ``refine_threshold`` (and
            that survive non-maximum suppression among them) are cropped again at each further
            scale. A wider crop replaces the first when the head scores it higher *and* boxes
            the target at least as large as the first crop (the target did not fit in it); a
            small target keeps the finer first crop's box. The default ``(1.0, 2.0)`` lets the
            head see (and box) the 25-40 px swimmers that a 16 px crop cuts, for a few more
            crops per frame; ``(1.0,)`` is the paper's single crop.
        refine_threshold: first-crop score from which a proposal is cropped at the further
            scales; None = ``score_threshold`` (only would-be detections are refined), 0 = every
            proposal. What each setting was measured to do: docs/experiments.md.
        recentre: crop once more, at the first scale, where the head put the target's centre
            (when that is at least :data:`RECENTRE_MIN_SHIFT_PX` off the proposal's and the first
            crop scored at least :data:`RECENTRE_MIN_SCORE`); the second crop's score, class and
            box replace the first's, and further scales are cut around the new centre. The
            proposals miss small targets by several pixels (the response lags a moving target),
            so a 16-px crop can hold a tiny target at its edge. Measured: docs/recentring.md.
        orientations: 1, 4 or 8: every crop that scores at least ``score_threshold`` is scored
            again turned by quarter turns (4) or by every symmetry of the square (8), and its
            class probabilities and box are the mean over the orientations
            (:mod:`~sarmission.perception.orientations`; 1: the single look of the paper).
        fit_boxes: replace the box of each detection scored at least :data:`FIT_MIN_SCORE`
            (the :data:`FIT_MAX_PER_FRAME` best-scored) by the object's extent against its
            surroundings (:func:`~sarmission.perception.extent.fit_boxes`) where that is longer
            than the head's box and at most :data:`FIT_MAX_SIDE_S` x S: the head boxes what its
            16 px crop shows, a torso for a person lying 30-50 px long. Scores and classes are
            the head's. Measured: docs/box_fit.md.
        range_shift_per_octave: with a person's expected size at each proposal
            (``process(person_px=...)``), every crop of a proposal where a person spans more
            than S grows by that factor ``k`` (at most :data:`MAX_RANGE_FACTOR`), and its class
            logits are lowered by this much per doubling of ``k``: the head scores a whole
            person in a wider crop higher, and clutter too, so a scaled crop's score is brought
            back to the survey's meaning. Measured: docs/range_crops.md.
    """

    def __init__(
        self,
        head_runtime: HeadRuntime,
        ds: int = 2,
        topn: int = 25,
        target_size: float | None = None,
        box_size: float = 16.0,
        score_threshold: float = 0.3,
        classes: tuple[str, ...] | None = None,
        nms_iou: float | None = 0.5,
        ego_motion: str = "estimate",
        colour_share: float = DEFAULT_COLOUR_SHARE,
        crop_scales: tuple[float, ...] = DEFAULT_CROP_SCALES,
        refine_threshold: float | None = None,
        recentre: bool = False,
        orientations: int = 1,
        fit_boxes: bool = True,
        range_shift_per_octave: float = 0.0,
    ) -> None:
        if classes is not None and tuple(classes) != tuple(head_runtime.classes):
            raise ValueError(
                f"classes {tuple(classes)} differ from the head's {tuple(head_runtime.classes)}"
            )
        if not 0.0 <= score_threshold <= 1.0:
            raise ValueError(f"score_threshold must be in [0, 1], got {score_threshold}")
        if not crop_scales or any(not (s > 0 and math.isfinite(s)) for s in crop_scales):
            raise ValueError(f"crop_scales must be positive numbers, got {crop_scales!r}")
        if refine_threshold is not None and not 0.0 <= refine_threshold <= 1.0:
            raise ValueError(f"refine_threshold must be in [0, 1], got {refine_threshold}")
        if not (math.isfinite(range_shift_per_octave) and range_shift_per_octave >= 0.0):
            raise ValueError(
                f"range_shift_per_octave must be a number >= 0, got {range_shift_per_octave!r}"
            )
        self.range_shift_per_octave = float(range_shift_per_octave)
        self.crop_scales = tuple(float(s) for s in crop_scales)
        self.refine_threshold = score_threshold if refine_threshold is None else refine_threshold
        self.recentre = bool(recentre)
        self.orientations = check_orientations(orientations)
        self.fit_boxes = bool(fit_boxes)
        if self.fit_boxes:
            extent.prepare()
        self.head = head_runtime
        self.ds = ds
        self.topn = topn
        self.box_size = box_size
        self.score_threshold = score_threshold
        self.nms_iou = nms_iou
        size = {} if target_size is None else {"target_size": target_size}
        self.vstmd = VSTMD(ds=ds, ego_motion=ego_motion, **size)
        self.rpn = TTMRPN(topn=topn, box_size=box_size, colour_share=colour_share)
        self.per_stage_ms: dict[str, float] = {}
        self._frame_shape: tuple[int, int] | None = None

    @property
    def classes(self) -> tuple[str, ...]:
        """Class names, index = class id."""
        return self.head.classes

    @property
    def motion_floor(self) -> float:
        """The head's motion floor: part of how its input crops are cut."""
        return self.head.config.motion_floor

    def reset(self) -> None:
        """Forget the motion state and the frame size: the next frame starts a new stream."""
        self.vstmd.reset()
        self._frame_shape = None
        self.per_stage_ms = {}

    def _check_frame(self, frame: np.ndarray | YuvImage) -> None:
        if isinstance(frame, YuvImage):
            shape = (frame.height, frame.width)
        else:
            if not isinstance(frame, np.ndarray):
                raise ValueError(f"frame must be a numpy array, got {type(frame).__name__}")
            if frame.dtype != np.uint8:
                raise ValueError(f"frame must be uint8 BGR, got dtype {frame.dtype}")
            if frame.ndim != 3 or frame.shape[2] != 3:
                raise ValueError(f"frame must have shape [H, W, 3] (BGR), got {list(frame.shape)}")
            shape = (int(frame.shape[0]), int(frame.shape[1]))
        if min(shape) < self.ds or min(shape) < 2:
            raise ValueError(f"frame {shape[1]}x{shape[0]} is too small for ds={self.ds}")
        if self._frame_shape is not None and shape != self._frame_shape:
            raise ValueError(
                f"frame size changed mid-stream from {self._frame_shape[1]}x"
                f"{self._frame_shape[0]} to {shape[1]}x{shape[0]}; call reset() "
                "before a new stream"
            )
        self._frame_shape = shape

    def process(
        self,
        frame_bgr: np.ndarray | YuvImage,
        timestamp: float,
        shift_px: tuple[float, float] | None = None,
        person_px: Callable[[np.ndarray], np.ndarray] | None = None,
    ) -> FrameResult:
        """Run the cascade on the next frame of the stream: BGR uint8 ``[H, W, 3]``, or the
        decoder's YUV planes (:class:`~sarmission.yuv.YuvImage`), of which vSTMD reads the Y
        plane, the chroma map the U and V planes and the head the BGR of its crops alone (the
        same detections, to within the rounding of the conversion).

        ``shift_px`` is the image motion since the previous frame in full-resolution pixels, when
        it is known (e.g. from telemetry); it overrides vSTMD's own ego-motion estimate.

        ``person_px``, when the camera's pose is known, maps proposal centres ``[N, 2]`` to the
        pixels a person would span there (NaN where unknown): the crops of a proposal where that
        is more than S grow to hold the person (``range_shift_per_octave``); without it every
        crop is cut as at the survey's ranges.

        Detections are full-resolution ``xyxy`` boxes with the best class's probability and id;
        ``per_stage_ms`` holds this frame's wall time per stage (``vstmd``, ``rpn``, ``crops``,
        ``head``, ``fit``; ``crops`` is the first scale's, ``head`` includes the further scales'
        crops, the decoding and NMS, ``fit`` the boxes' fitting). The arrays of
        ``result.motion`` belong to the vSTMD model and stay valid until the next call (copy
        them to keep them).
        """
        self._check_frame(frame_bgr)
        t0 = time.perf_counter()
        colour = self.rpn.colour_slots > 0
        if isinstance(frame_bgr, YuvImage):
            frame: np.ndarray | YuvImage = frame_bgr
            motion = self._motion_from_luma(frame_bgr, shift_px)
            t1 = time.perf_counter()
            chroma = chroma_if_wanted(frame_bgr, colour)
        else:
            frame = np.ascontiguousarray(frame_bgr)
            # One full-resolution pass shared by vSTMD (ds >= 2) and the chroma map.
            half = half_resolution(frame) if self.ds >= 2 or colour else None
            motion = self.vstmd.step(frame, shift_px=shift_px, half=half)
            t1 = time.perf_counter()
            chroma = chroma_if_wanted(frame, colour, half)
        t2 = time.perf_counter()
        proposals = self.rpn.propose(motion, chroma)
        t3 = time.perf_counter()
        factors = self.range_factors(proposals.boxes, person_px)
        first = scaled_boxes(proposals.boxes, self.crop_scales[0] * factors)
        crops = motion_enhanced_crops(
            frame, motion, first, proposals.polarity, motion_floor=self.motion_floor
        )
        t4 = time.perf_counter()
        shift = self.range_shift_per_octave * np.log2(factors)
        detections = self._detect(frame, motion, proposals, crops, first, factors, shift)
        t5 = time.perf_counter()
        detections = self.fitted(frame, detections)
        t6 = time.perf_counter()
        self.per_stage_ms = {
            "vstmd": (t1 - t0) * 1e3,
            "colour": (t2 - t1) * 1e3,
            "rpn": (t3 - t2) * 1e3,
            "crops": (t4 - t3) * 1e3,
            "head": (t5 - t4) * 1e3,
            "fit": (t6 - t5) * 1e3,
        }
        return FrameResult(
            timestamp=float(timestamp),
            detections=detections,
            proposals=proposals,
            motion=motion,
            camera_shift=self.vstmd.last_shift,
        )

    def range_factors(
        self, boxes: np.ndarray, person_px: Callable[[np.ndarray], np.ndarray] | None
    ) -> np.ndarray:
        """How much each proposal's crops grow: the pixels a person spans at its centre over
        S, within ``[1, MAX_RANGE_FACTOR]``; 1 where unknown or without ``person_px``."""
        factors = np.ones(len(boxes))
        if person_px is None or not len(boxes):
            return factors
        centres = (np.asarray(boxes[:, :2], float) + np.asarray(boxes[:, 2:], float)) / 2
        pixels = np.asarray(person_px(centres), dtype=float).reshape(-1)
        if pixels.shape != factors.shape:
            raise ValueError(f"person_px gave {pixels.shape[0]} sizes for {len(boxes)} centres")
        known = np.isfinite(pixels)
        factors[known] = np.clip(pixels[known] / self.box_size, 1.0, MAX_RANGE_FACTOR)
        return factors

    def fitted(self, frame: np.ndarray | YuvImage, detections: Detections) -> Detections:
        """``detections`` of ``frame`` with their boxes fitted to the object as ``fit_boxes``
        says (the class docstring); unchanged when it is off."""
        if not self.fit_boxes:
            return detections
        sure = np.flatnonzero(detections.scores >= FIT_MIN_SCORE)
        sure = sure[np.argsort(-detections.scores[sure], kind="stable")[:FIT_MAX_PER_FRAME]]
        if not len(sure):
            return detections
        boxes = detections.boxes.copy()
        boxes[sure], _ = fit_boxes(frame, boxes[sure], FIT_MAX_SIDE_S * self.box_size)
        return Detections(boxes, detections.scores, detections.class_ids)

    def _motion_from_luma(
        self, image: YuvImage, shift_px: tuple[float, float] | None
    ) -> MotionMaps:
        """vSTMD on the picture's gray, taken from its Y plane: at ds >= 2 only the
        half-resolution gray is made (vSTMD then reads the full frame's size alone)."""
        if self.ds == 1:
            return self.vstmd.step(image.to_gray(image.y), shift_px=shift_px)
        half = image.to_gray(half_resolution(image.y))
        return self.vstmd.step(image.y, shift_px=shift_px, half=half)

    def _classify(
        self, crops: np.ndarray, logit_shift: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Best class probability, its class id and the box bins of every crop; each crop's
        class logits lowered by its ``logit_shift`` (none: 0)."""
        logits, ltrb = self.head.predict(crops)
        probs = _sigmoid(_shifted(logits, logit_shift))
        if self.orientations > 1:
            self._average_orientations(crops, probs, ltrb, logit_shift)
        class_ids = probs.argmax(axis=1)
        return probs[np.arange(len(probs)), class_ids], class_ids, ltrb

    def _average_orientations(
        self,
        crops: np.ndarray,
        probs: np.ndarray,
        ltrb: np.ndarray,
        logit_shift: np.ndarray | None = None,
    ) -> None:
        """Replace, in place, the probabilities and boxes of the crops scoring at least the
        detection threshold by their means over :attr:`orientations` orientations."""
        sure = np.flatnonzero(probs.max(axis=1) >= self.score_threshold)
        if sure.size == 0:
            return
        ops = range(1, self.orientations)
        chosen = crops[sure]
        logits, turned = self.head.predict(
            np.concatenate([oriented_crops(chosen, op) for op in ops])
        )
        prob_sum, ltrb_sum = probs[sure].copy(), ltrb[sure].astype(np.float64)
        for i, op in enumerate(ops):
            view = slice(i * sure.size, (i + 1) * sure.size)
            prob_sum += _sigmoid(
                _shifted(logits[view], None if logit_shift is None else logit_shift[sure])
            )
            ltrb_sum += ltrb_from_orientation(turned[view], op)
        probs[sure] = prob_sum / self.orientations
        ltrb[sure] = ltrb_sum / self.orientations

    def _recentre(
        self,
        frame: np.ndarray | YuvImage,
        motion: MotionMaps,
        polarity: np.ndarray,
        scores: np.ndarray,
        class_ids: np.ndarray,
        ltrb: np.ndarray,
        boxes: np.ndarray,
        logit_shift: np.ndarray,
    ) -> None:
        """Classify again the crops whose target the head placed off their centre, cut around
        the head's box centre; the results replace the first crop's in place."""
        seen = ltrb_to_boxes(ltrb, boxes, self.head.config.crop_size)
        centre = (seen[:, :2] + seen[:, 2:]) / 2
        shift = centre - (boxes[:, :2] + boxes[:, 2:]) / 2
        moved = np.flatnonzero(
            (scores >= RECENTRE_MIN_SCORE)
            & (np.hypot(shift[:, 0], shift[:, 1]) >= RECENTRE_MIN_SHIFT_PX)
        )
        if moved.size == 0:
            return
        again = boxes[moved] + np.tile(shift[moved], 2)
        again_scores, again_ids, again_ltrb = self._classify(
            motion_enhanced_crops(
                frame, motion, again, polarity[moved], motion_floor=self.motion_floor
            ),
            logit_shift[moved],
        )
        scores[moved], class_ids[moved], ltrb[moved] = again_scores, again_ids, again_ltrb
        boxes[moved] = again

    def _detect(
        self,
        frame: np.ndarray | YuvImage,
        motion: MotionMaps,
        proposals: Proposals,
        crops: np.ndarray,
        boxes: np.ndarray,
        factors: np.ndarray | None = None,
        shift: np.ndarray | None = None,
    ) -> Detections:
        """Detections from the first-scale ``crops`` of ``boxes``, refined at the other scales;
        ``factors`` how much each proposal's crops grew, ``shift`` its logits' shift (none:
        crops as at the survey's ranges)."""
        if len(boxes) == 0:
            return Detections()
        if factors is None or shift is None:
            factors, shift = np.ones(len(boxes)), np.zeros(len(boxes))
        scores, class_ids, ltrb = self._classify(crops, shift)
        if self.recentre:
            self._recentre(frame, motion, proposals.polarity, scores, class_ids, ltrb, boxes, shift)
        refine = np.flatnonzero(scores >= self.refine_threshold)
        if self.nms_iou is not None and refine.size > 1 and len(self.crop_scales) > 1:
            first = ltrb_to_boxes(ltrb[refine], boxes[refine], self.head.config.crop_size)
            refine = refine[nms_xyxy(first, scores[refine], self.nms_iou)]
        # every proposal box is S x S, its crops grown by its factor
        first_side = self.crop_scales[0] * self.box_size * factors
        for scale in self.crop_scales[1:]:
            if refine.size == 0:
                break
            wide = scaled_boxes(boxes[refine], scale / self.crop_scales[0])
            # One bilinear sample per bin, as for the first crop: averaging 2 x 2 samples per bin
            # (RoIAlign's adaptive ratio at 2 S) costs more and changed nothing measurable.
            wide_scores, wide_ids, wide_ltrb = self._classify(
                motion_enhanced_crops(
                    frame,
                    motion,
                    wide,
                    proposals.polarity[refine],
                    sampling_ratio=1,
                    motion_floor=self.motion_floor,
                ),
                shift[refine],
            )
            seen = ltrb_to_boxes(wide_ltrb, wide, self.head.config.crop_size)
            larger = np.maximum(seen[:, 2] - seen[:, 0], seen[:, 3] - seen[:, 1])
            larger = larger >= first_side[refine]
            better = (wide_scores > scores[refine]) & larger
            chosen = refine[better]
            scores[chosen], class_ids[chosen] = wide_scores[better], wide_ids[better]
            ltrb[chosen], boxes[chosen] = wide_ltrb[better], wide[better]
        keep = np.flatnonzero(scores >= self.score_threshold)
        boxes = ltrb_to_boxes(ltrb[keep], boxes[keep], self.head.config.crop_size)
        scores, class_ids = scores[keep], class_ids[keep]
        if self.nms_iou is not None and len(keep) > 1:
            kept = nms_xyxy(boxes, scores, self.nms_iou)
            boxes, scores, class_ids = boxes[kept], scores[kept], class_ids[kept]
        return Detections(
            boxes=boxes.astype(np.float32),
            scores=scores.astype(np.float32),
            class_ids=class_ids.astype(np.int64),
        )

    def complexity(self, height: int, width: int) -> dict[str, dict[str, int]]:
        """Parameters and FLOPs per frame of each stage for ``height x width`` frames (Table 4).

        ``flops``: ``vstmd`` (``VSTMD.flops``), ``rpn_other`` (``TTMRPN.flops`` on the 1/ds maps,
        the chromatic anomaly map when colour proposals are on, and the N crops), ``head``
        (2 x MACs of every conv/linear per proposal, times N and the crops per proposal: one per
        crop scale, one more when recentring, all of it times the orientations: the most a frame
        can cost), ``total``. N is ``topn``, the most proposals a
        frame can have. ``parameters``: ``head`` (learned) and ``total`` (vSTMD and
        the RPN learn nothing).
        """
        from sarmission.perception.head import MiteHead, count_parameters, head_flops_per_proposal

        head = MiteHead(HeadConfig.from_dict(self.head.config.to_dict()))
        map_h, map_w = self.vstmd.map_shape(height, width)
        colour = self.rpn.colour_slots > 0 and chroma_applies(height, width)
        chroma_shape = (height // CHROMA_SCALE, width // CHROMA_SCALE) if colour else None
        crops = self.topn * (len(self.crop_scales) + int(self.recentre))
        flops = {
            "vstmd": int(self.vstmd.flops(height, width)),
            "rpn_other": (
                int(self.rpn.flops(map_h, map_w, chroma_shape))
                + crop_flops(crops, CROP_SIZE)
                + (chroma_flops(height, width) if colour else 0)
                # the half-resolution frame is vSTMD's at ds >= 2, the map's own at 1
                + (height * width * 3 if colour and self.ds == 1 else 0)
            ),
            "head": head_flops_per_proposal(head) * crops * self.orientations,
        }
        flops["total"] = sum(flops.values())
        params = count_parameters(head)
        return {"parameters": {"head": params, "total": params}, "flops": flops}
