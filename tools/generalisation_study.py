"""Does the head generalise beyond its renderer? Train recipe variants over several seeds, test each
on the simulator's own test split and on held-out worlds -> docs/generalisation.md.

Every variant trains a reduced recipe (fewer and shorter clips, fewer epochs than
``tools/train_default_model.py``, so that one training fits a few minutes on 2 cores) with
training seeds :data:`SEEDS` and picks its epoch on the held-out validation clips of
``tools/train_default_model.py`` (``--val heldout``: clip indices from 100 on). Crops are cut once
per training set with crop seed 0 (GT jitter and background negatives); the training seed sets the
initial weights, the batch order, the symmetries and the randomisation draws.

Variants (:data:`VARIANTS`):

* ``baseline``: the shipped recipe's data (the simulator's maritime training presets), no
  randomisation.
* ``randomised``: the same data, crop-level domain randomisation of every transform
  (:mod:`sarmission.training.randomise`, half the crops each) and 8 background negatives per
  training frame.
* ``more_presets``: more of the simulator's presets: ``urban_train`` (people on land, trained as
  ``swimmer``), ``maritime_oblique_mid`` and ``maritime_oblique_high``, no randomisation.
* ``broad``: both, ``randomised`` on the ``more_presets`` data.
* ``broad_context``: ``broad`` with the context crops of ``broad_classes_context``.
* ``broad_objects``: ``broad`` plus ``maritime_objects_train`` (an oblique sea crowded with
  boats, jetskis, buoys and life rings), all of them background.
* ``broad_classes``: ``broad_objects`` with the maritime head's object classes
  (:data:`sarmission.class_roles.MARITIME_CLASSES`: boats, jetskis, buoys and
  life-saving appliances learnt as classes of their own instead of background).
* ``broad_classes_parts``: ``broad_classes`` with the RPN's proposals on part of a larger
  object of those classes labelled with its class (``sarmission train --object-parts``): NWD
  gives a proposal on a boat's stern or wake a negative, yet those are the crops inference
  classifies on boats.
* ``broad_classes_context``: ``broad_classes_parts`` with two context crops per target box
  larger than S and two wide crops of open background per frame (``sarmission train
  --object-context 2``): the 16-px crop sees a boat's cabin, a crop of 8 S the whole boat
  (``--crop-scales 1,2,4,8`` at inference).
* ``broad_person``: ``broad`` with people on land learnt as ``person``, a class of their own
  beside the swimmers (validated so; the land test scores any person class).
* ``broad_textures``: ``broad`` plus procedural texture negatives (dead leaves, fractal noise,
  gratings, edges; :mod:`sarmission.training.textures`), a quarter of each batch's size, each
  with the motion channel of a random training crop.
* ``broad_textures_paste``: ``broad_textures`` with a quarter of the positives put on a
  texture too (their surroundings replaced), so that textures alone do not mean nobody.
* ``broad_wild``: ``broad`` plus the simulator's wild land (meadow, forest, rock, snow and
  sand with animals and person-sized clutter; people trained as ``swimmer``), a clip of each.
* ``broad_wild_textures``: ``broad_wild`` with the texture negatives of ``broad_textures``.
* ``broad_wild_floor``: ``broad_wild`` with a motion floor (:data:`MOTION_FLOOR`): crops whose
  temporal change is below it keep a faint motion channel instead of stretched noise.
* ``broad_wild_rounding``: ``broad_wild`` with the rounding-consistency term
  (:mod:`sarmission.training.consistency`, weight :data:`ROUNDING_WEIGHT`): the head's scores
  of a crop and of its copy as another decoder would round it (shifted by a pixel or two, the
  motion channel moved) are kept together.
* ``broad_wild_norm``: ``broad_wild`` with each crop's colour seen relative to the crop
  (``sarmission train --crop-norm 0.05``): its mean colour taken away and divided by its
  spread (at least 0.05), so a sea or field of another tone or contrast looks the same to the
  head.
* ``broad_wild_norm15``: the same with the spread floored at 0.15: an empty crop's noise is
  stretched less.
* ``broad_wild_centre``: ``broad_wild`` with each crop's mean colour taken away, its contrast
  kept (``--crop-norm 1``).
* ``broad_distractors``: ``broad`` plus two negatives cut around every annotated distractor
  of each training frame (``--object-negatives 2``: boats, debris, birds, sun glints).

Test (the clips and seeds of ``tools/heldout_eval.py``, rendered with its functions):
``maritime_test`` (own renderer, 2 x 40 frames), ``heldout_maritime`` (3 x 40) and
``heldout_land`` (2 x 40, people scored as ``swimmer``). Detector: the ``sarmission eval``
defaults (ds 2, N 25, conf 0.3, lock 3 of 5 at score > 0.5 and NWD > 0.5), torch runtime; vSTMD
and the RPN run once per frame and every head classifies the same crops (cut once per motion
floor, :func:`run_heads`), which is what running ``sarmission eval --model`` per head gives, at a
fraction of the cost. The shipped head is evaluated beside the variants for reference::

    nice -n 19 python tools/generalisation_study.py                  # renders, trains, tests
    nice -n 19 python tools/generalisation_study.py --variants baseline,randomised --seeds 0,1,2
    python tools/generalisation_study.py --from-json \
        /tmp/sarmission-generalisation/generalisation_results.json

Measured numbers go to ``<work>/generalisation_results.json``; the Markdown is a pure function of
it (:func:`render_section`). Runs already trained (a checkpoint and its entry in the JSON) are
not trained again.
"""

from __future__ import annotations

import argparse
import datetime as dt
import importlib.util
import json
import os
import platform
import shlex
import sys
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from types import ModuleType
from typing import Any

from sarmission.class_roles import MARITIME_CLASSES
from sarmission.perception.head_config import DEFAULT_CLASSES

REPO = Path(__file__).resolve().parents[1]
TOOLS = Path(__file__).resolve().parent
DEFAULT_DOC = REPO / "docs" / "generalisation.md"
BEGIN = "<!-- generated by tools/generalisation_study.py: begin -->"
END = "<!-- generated by tools/generalisation_study.py: end -->"

#: Training seeds of every variant.
SEEDS = (0, 1, 2)
#: Reduced recipe: (preset, clips, frames per clip, frame size) of the simulator.
MARITIME_PARTS = (
    ("maritime_train", 3, 40, "3840x2160"),
    ("maritime_train_high", 2, 40, "3840x2160"),
    ("maritime_train_narrow", 3, 40, "960x540"),
)
EXTRA_PARTS = (
    ("urban_train", 2, 40, "3840x2160"),
    ("maritime_oblique_mid", 2, 40, "3840x2160"),
    ("maritime_oblique_high", 2, 40, "3840x2160"),
)
OBJECT_PARTS = (("maritime_objects_train", 3, 40, "3840x2160"),)
WILD_PARTS = tuple(
    (f"wild_{biome}_train", 1, 40, "3840x2160")
    for biome in ("meadow", "forest", "rock", "snow", "sand")
)
TRAIN_SETTINGS = {
    "epochs": 12,
    "select_from": 4,
    "batch_size": 64,
    "lr": 0.02,
    "frame_stride": 3,
    "jitters_per_gt": 4,
    "ds": 1,
}
#: Test clips: tools/heldout_eval.py's defaults.
TEST_FRAMES, OWN_CLIPS, SEA_CLIPS, LAND_CLIPS = 40, 2, 3, 2
#: Background-only held-out worlds (tools/background_eval.py) and their clips of TEST_FRAMES.
BACKGROUND_SPLITS, BACKGROUND_CLIPS = ("heldout_land_empty", "heldout_maritime_empty"), 3
#: Motion floor of the floor variant: 5 grey levels of frame-to-frame change, above what sensor
#: noise and compression leave on still ground and below what a moving person makes.
MOTION_FLOOR = 0.02
#: Weight of the rounding-consistency term of ``broad_wild_rounding``.
ROUNDING_WEIGHT = 10.0
#: Detector settings of ``sarmission eval``.
EVAL_DS, EVAL_TOPN, EVAL_CONF = 2, 25, 0.3


@dataclass(frozen=True)
class Variant:
    """A recipe variant: its training presets, randomised transforms and background negatives."""

    name: str
    parts: tuple[tuple[str, int, int, str], ...]
    randomise: str
    background_negatives: int
    description: str
    classes: tuple[str, ...] = DEFAULT_CLASSES
    object_negatives: int = 0
    #: RPN proposals on part of a larger object of a head class labelled with that class
    #: (:func:`sarmission.training.dataset.part_of_objects`) rather than as negatives.
    object_parts: bool = False
    #: Context crops per target box larger than S and per frame (``sarmission train
    #: --object-context``).
    object_context: int = 0
    #: The crop scales the variant's heads are tested with (None: the detector's default).
    crop_scales: tuple[float, ...] | None = None
    #: People on land learnt as ``person`` (a class of their own; validation keeps them so)
    #: instead of as ``swimmer``.
    land_person: bool = False
    #: Procedural texture negatives per batch, as a share of the batch size.
    texture_negatives: float = 0.0
    #: Share of the positives put on a procedural texture.
    texture_positives: float = 0.0
    #: The head's motion floor (``sarmission train --motion-floor``; 0: per-crop max-abs).
    motion_floor: float = 0.0
    #: Weight of the rounding-consistency term (``sarmission train --rounding-consistency``).
    rounding_consistency: float = 0.0
    #: The head sees each crop's colour relative to the crop, its spread floored at this
    #: (``sarmission train --crop-norm``; 0: raw colour, 1: centred only).
    crop_norm: float = 0.0


VARIANTS: dict[str, Variant] = {
    v.name: v
    for v in (
        Variant(
            "baseline", MARITIME_PARTS, "none", 0, "maritime training presets, no randomisation"
        ),
        Variant(
            "randomised",
            MARITIME_PARTS,
            "all",
            8,
            "maritime presets, every randomisation (p 0.5), 8 background negatives per frame",
        ),
        Variant(
            "more_presets",
            MARITIME_PARTS + EXTRA_PARTS,
            "none",
            0,
            "maritime presets plus urban_train (people as swimmer) and the oblique maritime "
            "presets, no randomisation",
        ),
        Variant(
            "broad",
            MARITIME_PARTS + EXTRA_PARTS,
            "all",
            8,
            "randomised, plus urban_train (people as swimmer) and the oblique maritime presets",
        ),
        Variant(
            "broad_context",
            MARITIME_PARTS + EXTRA_PARTS,
            "all",
            8,
            "broad, plus 2 context crops (2-8 S) per target box larger than S and 2 of open "
            "background per frame",
            object_context=2,
        ),
        Variant(
            "broad_objects",
            MARITIME_PARTS + EXTRA_PARTS + OBJECT_PARTS,
            "all",
            8,
            "broad, plus maritime_objects_train (boats, jetskis, buoys and life rings) as "
            "background",
        ),
        Variant(
            "broad_classes",
            MARITIME_PARTS + EXTRA_PARTS + OBJECT_PARTS,
            "all",
            8,
            "broad_objects, with boats, jetskis, buoys and life-saving appliances as classes "
            "of their own",
            MARITIME_CLASSES,
        ),
        Variant(
            "broad_classes_parts",
            MARITIME_PARTS + EXTRA_PARTS + OBJECT_PARTS,
            "all",
            8,
            "broad_classes, with the RPN's proposals on part of a larger boat, jetski, buoy or "
            "life-saving appliance labelled with its class instead of as negatives",
            MARITIME_CLASSES,
            object_parts=True,
        ),
        Variant(
            "broad_classes_context",
            MARITIME_PARTS + EXTRA_PARTS + OBJECT_PARTS,
            "all",
            8,
            "broad_classes_parts, with 2 context crops (2-8 S) per target box larger than S "
            "and 2 of open background per frame",
            MARITIME_CLASSES,
            object_parts=True,
            object_context=2,
        ),
        Variant(
            "broad_person",
            MARITIME_PARTS + EXTRA_PARTS,
            "all",
            8,
            "broad, with people on land as a class of their own (person) beside the swimmers",
            (*DEFAULT_CLASSES, "person"),
            land_person=True,
        ),
        Variant(
            "broad_distractors",
            MARITIME_PARTS + EXTRA_PARTS,
            "all",
            8,
            "broad, plus 2 negatives cut around every annotated distractor (boats, debris, "
            "birds, glints) in each training frame",
            object_negatives=2,
        ),
        Variant(
            "broad_textures",
            MARITIME_PARTS + EXTRA_PARTS,
            "all",
            8,
            "broad, plus procedural texture negatives (a quarter of each batch) carrying "
            "the motion channel of random training crops",
            texture_negatives=0.25,
        ),
        Variant(
            "broad_textures_paste",
            MARITIME_PARTS + EXTRA_PARTS,
            "all",
            8,
            "broad_textures, with a quarter of the positives put on a texture",
            texture_negatives=0.25,
            texture_positives=0.25,
        ),
        Variant(
            "broad_wild",
            MARITIME_PARTS + EXTRA_PARTS + WILD_PARTS,
            "all",
            8,
            "broad, plus the wild land presets (meadow, forest, rock, snow, sand; people as "
            "swimmer)",
        ),
        Variant(
            "broad_wild_norm",
            MARITIME_PARTS + EXTRA_PARTS + WILD_PARTS,
            "all",
            8,
            "broad_wild, with each crop's colour seen relative to the crop (its mean colour "
            "taken away, divided by its spread, at least 0.05)",
            crop_norm=0.05,
        ),
        Variant(
            "broad_wild_norm15",
            MARITIME_PARTS + EXTRA_PARTS + WILD_PARTS,
            "all",
            8,
            "broad_wild_norm with the spread floored at 0.15",
            crop_norm=0.15,
        ),
        Variant(
            "broad_wild_centre",
            MARITIME_PARTS + EXTRA_PARTS + WILD_PARTS,
            "all",
            8,
            "broad_wild, with each crop's mean colour taken away (its contrast kept)",
            crop_norm=1.0,
        ),
        Variant(
            "broad_wild_floor",
            MARITIME_PARTS + EXTRA_PARTS + WILD_PARTS,
            "all",
            8,
            f"broad_wild, with a motion floor of {MOTION_FLOOR} ({MOTION_FLOOR * 255:.0f} grey "
            "levels): a crop whose temporal change stays below it keeps a faint motion channel",
            motion_floor=MOTION_FLOOR,
        ),
        Variant(
            "broad_wild_textures",
            MARITIME_PARTS + EXTRA_PARTS + WILD_PARTS,
            "all",
            8,
            "broad_wild, plus the texture negatives of broad_textures",
            texture_negatives=0.25,
        ),
        Variant(
            "broad_wild_rounding",
            MARITIME_PARTS + EXTRA_PARTS + WILD_PARTS,
            "all",
            8,
            f"broad_wild, with a rounding-consistency term of weight {ROUNDING_WEIGHT:g}: the "
            "class scores of a crop and of its copy as another decoder would round it "
            "(shifted by a pixel or two, the motion channel moved) are kept together",
            rounding_consistency=ROUNDING_WEIGHT,
        ),
    )
}


def _tool(name: str) -> ModuleType:
    """Another script of tools/, imported by path."""
    spec = importlib.util.spec_from_file_location(f"sarmission_tool_{name}", TOOLS / f"{name}.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module
    spec.loader.exec_module(module)
    return module


def training_file(work: Path, variant: Variant) -> Path:
    """Render the variant's presets and merge them into one annotation file (people as swimmer)."""
    from sarmission.data.coco_video import write_coco_video
    from sarmission.data.merge import merge_annotation_files

    recipe = _tool("train_default_model")
    names = [p[0] for p in variant.parts]
    suffix = "_land_person" if variant.land_person else ""
    merged = work / f"train_{'_'.join(sorted(names))}{suffix}.json"
    if not merged.is_file():
        paths = [recipe.render(work / "sim" / part[0], part) for part in variant.parts]
        rename = {} if variant.land_person else recipe.HELDOUT_RENAME
        write_coco_video(merge_annotation_files(paths, rename, info={"presets": names}), merged)
    return merged


def validation_file(work: Path, variant: Variant) -> Path:
    """The held-out validation clips, people on land as the variant learns them."""
    recipe = _tool("train_default_model")
    if variant.land_person:
        return recipe.render_heldout_val(work, rename={}, name="heldout_val_land_person")
    return recipe.render_heldout_val(work)


def train_run(work: Path, variant: Variant, seed: int, train: Path, val: Path) -> dict[str, Any]:
    """Train one variant with one seed; the checkpoint and the training summary."""
    from sarmission.training.dataset import CropSettings
    from sarmission.training.randomise import Randomisation
    from sarmission.training.train import TrainConfig
    from sarmission.training.train import train as train_head

    s = TRAIN_SETTINGS
    out = work / "runs" / variant.name / f"seed{seed}" / "head.pt"
    crops = CropSettings(
        classes=variant.classes,
        ds=s["ds"],
        frame_stride=s["frame_stride"],
        jitters_per_gt=s["jitters_per_gt"],
        background_negatives=variant.background_negatives,
        object_negatives=variant.object_negatives,
        object_parts=variant.object_parts,
        object_context=variant.object_context,
        seed=0,
        motion_floor=variant.motion_floor,
    )
    config = TrainConfig(
        train=train,
        val=val,
        out=out,
        epochs=s["epochs"],
        batch_size=s["batch_size"],
        lr=s["lr"],
        seed=seed,
        select_from=s["select_from"],
        crops=crops,
        randomise=Randomisation.parse(variant.randomise),
        texture_negatives=variant.texture_negatives,
        texture_positives=variant.texture_positives,
        rounding_consistency=variant.rounding_consistency,
        crop_norm=variant.crop_norm,
        cache_dir=work / "crop_cache",
        progress=False,
    )
    started = time.monotonic()
    result = train_head(config)
    return {
        "checkpoint": str(result.checkpoint),
        "best_epoch": result.best_epoch,
        "val_f2": result.best_f2,
        "train_crops": result.train_crops,
        "train_s": round(time.monotonic() - started, 1),
    }


def run_heads(
    heads: Mapping[str, Any],
    dataset: Any,
    crop_scales: Mapping[str, tuple[float, ...] | None] | None = None,
) -> dict[str, Any]:
    """Run MITE-Net with every head of ``heads`` (name -> HeadRuntime) over ``dataset``: vSTMD,
    the RPN and the first crops once per frame, each head's classification, refinement and NMS
    on them (:meth:`MiteNet._detect` and :meth:`MiteNet.fitted`, exactly as
    :meth:`MiteNet.process` calls them), at the crop
    scales ``crop_scales`` gives the head (absent or None: the default; the first scale must be
    the default's). Returns name -> :class:`~sarmission.evaluation.run_model.ModelRun`."""
    from sarmission.data.sequence import iter_sequence, sequence_ids
    from sarmission.evaluation.matching import FrameBoxes
    from sarmission.evaluation.run_model import NOMINAL_FPS, ModelRun
    from sarmission.perception.crops import motion_enhanced_crops
    from sarmission.perception.mitenet import MiteNet, scaled_boxes
    from sarmission.perception.types import DEFAULT_CROP_SCALES

    scales = {name: (crop_scales or {}).get(name) or DEFAULT_CROP_SCALES for name in heads}
    if len({s[0] for s in scales.values()}) > 1:
        raise ValueError("every head must share the first crop scale")
    nets = {
        name: MiteNet(
            head,
            ds=EVAL_DS,
            topn=EVAL_TOPN,
            score_threshold=EVAL_CONF,
            crop_scales=scales[name],
        )
        for name, head in heads.items()
    }
    driver = next(iter(nets.values()))
    runs = {name: ModelRun() for name in nets}
    counters: dict[str, int] = {}
    for video_id in sequence_ids(dataset):
        driver.reset()
        for position, item in enumerate(iter_sequence(dataset, video_id, counters)):
            frame = item.frame_bgr
            result = driver.process(frame, position / NOMINAL_FPS)
            prop = result.proposals
            first = scaled_boxes(prop.boxes, driver.crop_scales[0])
            crops: dict[float, Any] = {}  # motion floor -> first crops
            for name, net in nets.items():
                if net is not driver and net.motion_floor not in crops:
                    crops[net.motion_floor] = motion_enhanced_crops(
                        frame, result.motion, first, prop.polarity, motion_floor=net.motion_floor
                    )
                det = (
                    result.detections
                    if net is driver
                    else net.fitted(
                        frame,
                        net._detect(
                            frame,
                            result.motion,
                            prop,
                            crops[net.motion_floor].copy(),
                            first.copy(),
                        ),
                    )
                )
                run = runs[name]
                run.detections[item.image.id] = FrameBoxes.of(det.boxes, det.scores, det.class_ids)
                run.proposals[item.image.id] = FrameBoxes.of(prop.boxes, prop.scores)
                run.frame_ms.append(0.0)
    for run in runs.values():
        run.skipped = counters.get("skipped", 0)
    return runs


def figures(report: Mapping[str, Any]) -> dict[str, Any]:
    """The figures the study compares, from an evaluation report."""
    sar, mr, bands = report["sar"], report["module_recall"], report["boxes"]["bands"]
    return {
        "ap_all": bands["all"]["ap"],
        "et_recall": bands["extremely_tiny"]["recall"],
        "ssr": sar["search_success_rate"],
        "far_det": sar["false_alarm_rate_detections"],
        "locked": sar["n_locked"],
        "lockable": sar["n_lockable"],
        "head_r05": mr["head"]["R@0.5"],
        "head_r01": mr["head"]["R@0.1"],
        "rpn_r01": mr["rpn"]["R@0.1"],
    }


def test_splits(folder: Path) -> dict[str, Path]:
    """Render the test clips into ``folder`` with tools/heldout_eval.py's functions (a render
    already there with the right clip and frame counts is reused); split name -> annotations."""
    heldout_eval = _tool("heldout_eval")
    folder.mkdir(parents=True, exist_ok=True)
    reused: list[str] = []
    land = heldout_eval.render_heldout(folder, "heldout_land", LAND_CLIPS, TEST_FRAMES, reused)
    return {
        "maritime_test": heldout_eval.render_own(folder, OWN_CLIPS, TEST_FRAMES, reused),
        "heldout_maritime": heldout_eval.render_heldout(
            folder, "heldout_maritime", SEA_CLIPS, TEST_FRAMES, reused
        ),
        "heldout_land": heldout_eval.persons_as_swimmers(land),
    } | {
        name: heldout_eval.render_heldout(folder, name, BACKGROUND_CLIPS, TEST_FRAMES, reused)
        for name in BACKGROUND_SPLITS
    }


def evaluate_heads(
    checkpoints: Mapping[str, str | None],
    splits: Mapping[str, Path],
    crop_scales: Mapping[str, tuple[float, ...] | None] | None = None,
) -> dict[str, dict[str, Any]]:
    """Head name -> split -> :func:`figures`; a checkpoint ``None`` is the shipped head;
    ``crop_scales`` as :func:`run_heads`."""
    from sarmission.data.coco_video import read_coco_video
    from sarmission.evaluation.report import evaluate_detections
    from sarmission.models import DEFAULT_TORCH_MODEL
    from sarmission.perception.runtime import load_head_runtime

    heads = {
        name: load_head_runtime(path or DEFAULT_TORCH_MODEL, "torch")
        for name, path in checkpoints.items()
    }
    background = _tool("background_eval")
    out: dict[str, dict[str, Any]] = {name: {} for name in heads}
    for split, path in splits.items():
        print(f"testing {len(heads)} heads on {split}", file=sys.stderr)
        dataset = read_coco_video(path)
        for name, run in run_heads(heads, dataset, crop_scales).items():
            if split in BACKGROUND_SPLITS:
                out[name][split] = background.summarise(
                    [run.detections[i] for i in sorted(run.detections)]
                )
                continue
            report = evaluate_detections(
                dataset,
                run.detections,
                heads[name].classes,
                run.proposals,
                image_ids=run.image_ids,
                m=3,
                k=5,
                score_thr=0.5,
                nwd_thr=0.5,
            )
            out[name][split] = figures(report)
    return out


def measure(args: argparse.Namespace, previous: Mapping[str, Any] | None) -> dict[str, Any]:
    work = Path(args.work)
    work.mkdir(parents=True, exist_ok=True)
    started = time.monotonic()
    runs: dict[str, Any] = dict((previous or {}).get("runs", {}))
    for name in args.variants:
        variant = VARIANTS[name]
        train = training_file(work, variant)
        val = validation_file(work, variant)
        for seed in args.seeds:
            key = f"{name}/seed{seed}"
            if key in runs and Path(runs[key]["checkpoint"]).is_file():
                continue
            print(f"training {key}", file=sys.stderr)
            runs[key] = {
                "variant": name,
                "seed": seed,
                **train_run(work, variant, seed, train, val),
            }
            _save(work, {**(previous or {}), "runs": runs})
    if args.train_only:
        return {**(previous or {}), "runs": runs}
    splits = test_splits(Path(args.test_work) if args.test_work else work / "test")
    checkpoints: dict[str, str | None] = {"shipped": None}
    checkpoints |= {
        key: run["checkpoint"]
        for key, run in runs.items()
        if run["variant"] in args.variants and run["seed"] in args.seeds
    }
    scales = {key: VARIANTS[runs[key]["variant"]].crop_scales for key in checkpoints if key in runs}
    tests = evaluate_heads(checkpoints, splits, scales)
    for key, per_split in tests.items():
        if key in runs:
            runs[key]["test"] = per_split
    return {
        "command": "python tools/generalisation_study.py " + shlex.join(sys.argv[1:]),
        "generated": dt.datetime.now(dt.UTC).isoformat(timespec="seconds"),
        "wall_s": round(time.monotonic() - started, 1),
        "machine": {
            "nproc": os.cpu_count(),
            "python": platform.python_version(),
            "platform": platform.platform(),
        },
        "settings": {
            "seeds": list(args.seeds),
            "variants": list(args.variants),
            "test_work": str(args.test_work or work / "test"),
            "train": TRAIN_SETTINGS,
            "test_frames": TEST_FRAMES,
            "test_clips": {
                "maritime_test": OWN_CLIPS,
                "heldout_maritime": SEA_CLIPS,
                "heldout_land": LAND_CLIPS,
            }
            | dict.fromkeys(BACKGROUND_SPLITS, BACKGROUND_CLIPS),
        },
        "variants": {
            n: {
                "description": VARIANTS[n].description,
                "presets": [list(p) for p in VARIANTS[n].parts],
                "randomise": VARIANTS[n].randomise,
                "background_negatives": VARIANTS[n].background_negatives,
                "object_negatives": VARIANTS[n].object_negatives,
                "object_parts": VARIANTS[n].object_parts,
                "object_context": VARIANTS[n].object_context,
                "crop_scales": VARIANTS[n].crop_scales,
                "texture_negatives": VARIANTS[n].texture_negatives,
                "texture_positives": VARIANTS[n].texture_positives,
                "motion_floor": VARIANTS[n].motion_floor,
                "rounding_consistency": VARIANTS[n].rounding_consistency,
                "classes": list(VARIANTS[n].classes),
            }
            for n in args.variants
        },
        "runs": runs,
        "shipped": tests["shipped"],
    }


def _save(work: Path, results: Mapping[str, Any]) -> Path:
    out = work / "generalisation_results.json"
    out.write_text(json.dumps(results, indent=1))
    return out


# ---------------------------------------------------------------------------------- Markdown

SPLITS = ("maritime_test", "heldout_maritime", "heldout_land")
METRICS = (
    ("ssr", "SSR (%)", 1),
    ("far_det", "FAR/det (%)", 1),
    ("head_r05", "head R@0.5", 2),
    ("ap_all", "AP", 3),
    ("et_recall", "ET recall", 2),
)
#: Figures of the background-only worlds: false detections per frame above 0.5 and 0.9.
BACKGROUND_METRICS = (
    ("false_per_frame_above_0.5", "false/frame > 0.5", 2),
    ("false_per_frame_above_0.9", "false/frame > 0.9", 2),
)


def _figure(test: Mapping[str, Any], split: str, key: str) -> float | None:
    """One figure of a run's test results; ``None`` where it was not measured (results
    written before a split was added)."""
    value = test.get(split, {}).get(key)
    return None if value is None else float(value)


def spread(values: Sequence[float | None]) -> tuple[float, float, float] | None:
    """Mean, min and max of the known values; ``None`` when there are none."""
    known = [float(v) for v in values if v is not None]
    if not known:
        return None
    return sum(known) / len(known), min(known), max(known)


def _cell(stats: tuple[float, float, float] | None, digits: int) -> str:
    if stats is None:
        return "—"
    mean, lo, hi = stats
    return f"{mean:.{digits}f} ({lo:.{digits}f}-{hi:.{digits}f})"


def _num(value: float | None, digits: int) -> str:
    return "—" if value is None else f"{value:.{digits}f}"


def background_table(results: Mapping[str, Any]) -> list[str]:
    """Lines of the background-only table (false detections per frame where nobody is), mean
    (min-max) over the seeds; none when no run measured it."""
    runs = results["runs"]
    measured = [r for r in runs.values() if BACKGROUND_SPLITS[0] in r.get("test", {})]
    if not measured:
        return []
    header = [
        f"{split} {label}" for split in BACKGROUND_SPLITS for _, label, _ in BACKGROUND_METRICS
    ]
    lines = [
        "",
        "### Background only: false detections per frame, mean (min-max) over the seeds",
        "",
        "Held-out worlds with their people left out (`tools/background_eval.py`, "
        "docs/background_only.md): every detection is false; the land goal is 0.2 per frame.",
        "",
        "| variant | seeds | " + " | ".join(header) + " |",
        "| :--- | ---: |" + " ---: |" * len(header),
    ]
    for name in results["variants"]:
        mine = [r for r in measured if r["variant"] == name]
        cells = [
            _cell(spread([_figure(r["test"], split, key) for r in mine]), digits)
            for split in BACKGROUND_SPLITS
            for key, _, digits in BACKGROUND_METRICS
        ]
        lines.append(f"| `{name}` | {len(mine)} | " + " | ".join(cells) + " |")
    shipped = results.get("shipped") or {}
    if BACKGROUND_SPLITS[0] in shipped:
        cells = [
            _num(_figure(shipped, split, key), digits)
            for split in BACKGROUND_SPLITS
            for key, _, digits in BACKGROUND_METRICS
        ]
        lines.append(
            "| head shipped when generated (full recipe) | — | " + " | ".join(cells) + " |"
        )
    return lines


def render_section(results: Mapping[str, Any]) -> str:
    """The generated part of docs/generalisation.md."""
    s = results["settings"]
    t = s["train"]
    runs = results["runs"]
    lines = [
        BEGIN,
        "",
        f"Command: `{results['command']}` (generated {results['generated']}, "
        f"{results['wall_s'] / 60:.0f} min wall on {results['machine']['nproc']} cores shared "
        "with other work).",
        "",
        f"Training: seeds {', '.join(map(str, s['seeds']))} per variant; {t['epochs']} epochs, "
        f"epoch chosen from {t['select_from']} on by F2 on the held-out validation clips "
        f"(`tools/train_default_model.py --val heldout`), batch {t['batch_size']}, lr {t['lr']}, "
        f"crops at ds {t['ds']} every {t['frame_stride']} frames, {t['jitters_per_gt']} jittered "
        "copies per GT, crop seed 0. Test: "
        + ", ".join(f"`{k}` {v} x {s['test_frames']} frames" for k, v in s["test_clips"].items())
        + " (the clips of `tools/heldout_eval.py`); detector ds 2, N 25, conf 0.3, torch "
        "runtime.",
        "",
        "| variant | training data and randomisation |",
        "| :--- | :--- |",
    ]
    for name, v in results["variants"].items():
        presets = ", ".join(f"{p[0]} {p[1]}x{p[2]}" for p in v["presets"])
        lines.append(f"| `{name}` | {v['description']} ({presets}) |")
    lines += [
        "",
        "### Mean (min-max) over the seeds",
        "",
        "| variant | seeds | "
        + " | ".join(f"{split} {label}" for split in SPLITS for _, label, _ in METRICS)
        + " |",
        "| :--- | ---: |" + " ---: |" * (len(SPLITS) * len(METRICS)),
    ]
    for name in results["variants"]:
        mine = [r for r in runs.values() if r["variant"] == name and "test" in r]
        cells = [
            _cell(spread([_figure(r["test"], split, key) for r in mine]), digits)
            for split in SPLITS
            for key, _, digits in METRICS
        ]
        lines.append(f"| `{name}` | {len(mine)} | " + " | ".join(cells) + " |")
    shipped = results.get("shipped")
    if shipped:
        cells = [
            _num(_figure(shipped, split, key), digits)
            for split in SPLITS
            for key, _, digits in METRICS
        ]
        lines.append(
            "| head shipped when generated (full recipe) | — | " + " | ".join(cells) + " |"
        )
    lines += background_table(results)
    lines += [
        "",
        "### Every run",
        "",
        "| run | epoch | val F2 | train crops | train (min) | "
        + " | ".join(f"{split} locked" for split in SPLITS)
        + " | "
        + " | ".join(f"{split} {label}" for split in SPLITS for _, label, _ in METRICS)
        + " |",
        "| :--- | ---: | ---: | ---: | ---: |"
        + " ---: |" * len(SPLITS)
        + " ---: |" * (len(SPLITS) * len(METRICS)),
    ]
    for key, r in sorted(runs.items()):
        if "test" not in r:
            continue
        locked = [f"{r['test'][sp]['locked']}/{r['test'][sp]['lockable']}" for sp in SPLITS]
        cells = [_num(_figure(r["test"], sp, k), d) for sp in SPLITS for k, _, d in METRICS]
        lines.append(
            f"| `{key}` | {r['best_epoch']} | {r['val_f2']:.3f} | {r['train_crops']} "
            f"| {r['train_s'] / 60:.1f} | " + " | ".join(locked + cells) + " |"
        )
    lines += [
        "",
        "SSR: locked over lockable trajectories; FAR/det: unmatched detections with "
        "score > 0.5 over all such detections; head R@0.5: share of GT boxes within NWD 0.5 "
        "of a detection of the right class with score > 0.5; AP: the box AP of `sarmission "
        "eval` (every score, NWD 0.5-0.95; independent of a threshold, so heads whose scores "
        "run higher or lower compare fairly); ET recall: recall of the extremely tiny boxes "
        "(under 8 px across) at score > 0.5 (issue goal 0.5 on held-out). `heldout_land` is "
        "scored with people as `swimmer`; — where a run was tested before a figure existed.",
        "",
        END,
    ]
    return "\n".join(lines)


def _list(text: str) -> list[str]:
    return [t.strip() for t in text.split(",") if t.strip()]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--work",
        default="/tmp/sarmission-generalisation",
        help="folder for renders, crop caches, runs and results (default: %(default)s)",
    )
    parser.add_argument(
        "--variants",
        type=_list,
        default=list(VARIANTS),
        help=f"comma-separated, of {', '.join(VARIANTS)} (default: all)",
    )
    parser.add_argument(
        "--seeds",
        type=lambda t: [int(v) for v in _list(t)],
        default=list(SEEDS),
        help="training seeds (default: 0,1,2)",
    )
    parser.add_argument(
        "--test-work",
        default=None,
        help="folder of the test renders (default: <work>/test); renders of "
        "another version of heldout/ go in a folder of their own",
    )
    parser.add_argument(
        "--train-only",
        action="store_true",
        help="train the missing runs, test nothing, leave the page alone",
    )
    parser.add_argument("--doc", default=str(DEFAULT_DOC), help="Markdown file to update")
    parser.add_argument(
        "--from-json",
        default=None,
        help="re-render the Markdown from a results JSON, measuring nothing",
    )
    args = parser.parse_args(argv)
    if args.from_json:
        results = json.loads(Path(args.from_json).read_text())
    else:
        unknown = sorted(set(args.variants) - set(VARIANTS))
        if unknown or not args.variants or not args.seeds:
            parser.error(f"need known variants and seeds (unknown: {', '.join(unknown)})")
        previous_path = Path(args.work) / "generalisation_results.json"
        previous = json.loads(previous_path.read_text()) if previous_path.is_file() else None
        results = measure(args, previous)
        print(f"results: {_save(Path(args.work), results)}", file=sys.stderr)
        if args.train_only:
            return 0
    _tool("heldout_eval").write_doc(
        render_section(results), Path(args.doc), "# Generalisation beyond the simulator", BEGIN, END
    )
    print(f"wrote {args.doc}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
