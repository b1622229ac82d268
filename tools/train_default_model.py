"""Reproduce the default MITE-Net head shipped in ``sarmission/models``.

Renders the simulator's maritime training presets (``maritime_train`` at 70 m on a calm sea,
``maritime_train_high`` at 110 m on a rough one, both 4K, and ``maritime_train_narrow``, the
demo's 960x540 view) and :data:`BROAD_SPLITS` (``urban_train``, people on land trained as
``swimmer``, and the oblique maritime presets), merged into one training file, and the held-out
validation clips, and the simulator's wild land (:data:`WILD_SPLITS`, the default ``--presets
wild``); trains the head with ``sarmission train`` (seeded, deterministic on one CPU type;
crop-level domain randomisation and 8 background negatives per frame, :data:`TRAIN_ARGS`) with
seed 1 (the default ``--seed``) and writes ``mitenet_head.pt`` and ``mitenet_head.onnx`` into
the package::

    python tools/train_default_model.py            # about 35 minutes on 2 CPU cores, rendered
    python tools/train_default_model.py --work /tmp/sarmission-train --no-install
    python tools/train_default_model.py --presets broad --seed 0   # shipped 2026-11-25 to 28
    python tools/train_default_model.py --val sim --presets maritime --randomise none \
        --background-negatives 0 --seed 0          # the head shipped before 2026-11-25

The epoch is chosen on a validation split (``--val``): ``heldout`` (the default), clips of the
held-out worlds (:mod:`heldout`: ``heldout_maritime`` and ``heldout_land``, people on land scored
as ``swimmer``) from clip index :data:`HELDOUT_VAL_FIRST_CLIP` on, or ``sim``, the simulator's
``maritime_val``. ``tools/heldout_eval.py`` tests on clips 0, 1, 2 ...; indices below
:data:`HELDOUT_VAL_FIRST_CLIP` are kept for tests, so nothing is chosen on a test clip. Other
options go to ``sarmission train`` after :data:`TRAIN_ARGS`, so they override it.

``--altworld`` adds clips of the alternative training world (:mod:`altworld`, a renderer
of its own, docs/altworld.md; :data:`ALTWORLD_SPLITS`) to the training set (with ``--head
land``, its land clips alone, people as ``person``).
``--presets broad`` leaves the wild land presets out; other options, e.g.
``--texture-negatives 0.25``, go to ``sarmission train``.
``--presets floats`` adds ``maritime_floats_train`` (:data:`FLOAT_SPLITS`, people floating on
their back) to the wild recipe, ``--presets buoys`` ``maritime_buoys_train`` (round mooring
buoys, :data:`BUOY_SPLITS`), ``--presets buoys_high`` that and the same sea from 150 m
(:data:`BUOY_HIGH_SPLITS`); ``--presets objects`` adds ``maritime_objects_train``
(:data:`OBJECT_SPLITS`); ``--classes
maritime`` (an option of ``sarmission train``) trains the boats, jetskis, buoys and
life-saving appliances as classes of their own (:mod:`sarmission.class_roles`); ``--seed N``
trains another seed into ``mitenet_head_seed<N>.pt`` (seed 0 into ``mitenet_head.pt``), and
presets other than ``wild`` name the file too (``mitenet_head_floats_seed<N>.pt``).

``--head land`` reproduces the shipped land head (class ``person``, ``mitenet_land_head.pt``
and ``.onnx``, the mission's ``[detector] model = "land"``; docs/land_head.md): the weighted
mean (``sarmission export --average``, :data:`SHIPPED_LAND_WEIGHTS`, 3 to 1) of two heads
fine-tuned from the shipped maritime head (``--init default``, ``person`` from ``swimmer``),
each picking its epoch on the held-out land validation clips, people scored as ``person``: the
land recipe (:data:`LAND_WILD_SPLITS`, seed :data:`SHIPPED_LAND_SEED`, ``--seed``) and the same
with the alternative world's land (seed :data:`SHIPPED_LAND_ALTWORLD_SEED`,
``--altworld-seed``). ``--average-weights`` sets other weights. ``--single`` trains the land
recipe's head alone (the land head shipped 2026-11-28 to 29); so do ``--altworld`` (with the
alternative world's land), ``--from-scratch`` (random weights) and ``--land-presets urban``
(the recipe tried before the wild land presets existed); a single head is never installed::

    python tools/train_default_model.py --head land     # about 12 minutes on 2 CPU cores, rendered
    python tools/train_default_model.py --head land --single --no-install
    python tools/train_default_model.py --head land --average-weights 1,1 --no-install
    python tools/train_default_model.py --head land --land-presets urban --seed 0 --no-install

The rendered data (several GB of 4K video) stays in ``--work``; only the two small model files
are copied into the package.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import shutil
import sys
from pathlib import Path

from altworld.generate import render_world as render_altworld_world
from heldout.encode import ffmpeg_path
from heldout.generate import render_world
from heldout.presets import world
from sarmission.cli import main as sarmission
from sarmission.data.coco_video import read_coco_video, write_coco_video
from sarmission.data.merge import merge_annotation_files
from sarmission.models import (
    DEFAULT_TORCH_MODEL,
    is_head_name,
    shipped_checkpoint,
    shipped_head_path,
)
from sim.generate import merge_datasets

#: The recipe of the shipped model: (preset, clips, frames per clip, frame size) and the
#: training settings.
TRAIN_SPLITS = (
    ("maritime_train", 6, 90, "3840x2160"),
    ("maritime_train_high", 4, 90, "3840x2160"),
    ("maritime_train_narrow", 6, 90, "960x540"),
)
#: Added to :data:`TRAIN_SPLITS` by ``--presets broad``.
BROAD_SPLITS = (
    ("urban_train", 4, 90, "3840x2160"),
    ("maritime_oblique_mid", 3, 90, "3840x2160"),
    ("maritime_oblique_high", 3, 90, "3840x2160"),
)
#: Added to :data:`BROAD_SPLITS` by ``--presets objects``: a sea crowded with boats, jetskis,
#: buoys and life rings, for heads that learn them as classes (``--classes maritime``).
OBJECT_SPLITS = (("maritime_objects_train", 4, 90, "3840x2160"),)
#: Added to the wild recipe by ``--presets floats``: a sea where people float on their back in
#: about half the cases, most with arms and legs spread (docs/floating_people.md).
FLOAT_SPLITS = (("maritime_floats_train", 4, 90, "3840x2160"),)
#: Added to the wild recipe by ``--presets buoys``: a calm sea with a round mooring buoy for
#: every person in the water (docs/mooring_buoys.md).
BUOY_SPLITS = (("maritime_buoys_train", 4, 90, "3840x2160"),)
#: Added to the buoy recipe by ``--presets buoys_high``: the same sea from 150 m, buoys and
#: jacket wearers as small blobs (docs/box_colours.md).
BUOY_HIGH_SPLITS = (("maritime_buoys_high_train", 4, 90, "3840x2160"),)
#: Added to :data:`BROAD_SPLITS` by ``--presets wild``: the simulator's wild land (meadow,
#: forest, rock, snow, sand; people trained as ``swimmer``).
WILD_SPLITS = tuple(
    (f"wild_{biome}_train", 2, 90, "3840x2160")
    for biome in ("meadow", "forest", "rock", "snow", "sand")
)
#: ``--presets`` choice -> the splits added to :data:`TRAIN_SPLITS`.
EXTRA_SPLITS = {
    "maritime": (),
    "broad": BROAD_SPLITS,
    "objects": BROAD_SPLITS + OBJECT_SPLITS,
    "wild": BROAD_SPLITS + WILD_SPLITS,
    "floats": BROAD_SPLITS + WILD_SPLITS + FLOAT_SPLITS,
    "buoys": BROAD_SPLITS + WILD_SPLITS + BUOY_SPLITS,
    "buoys_high": BROAD_SPLITS + WILD_SPLITS + BUOY_SPLITS + BUOY_HIGH_SPLITS,
}
#: ``--altworld``: clips of the alternative training world (:mod:`altworld`, its own renderer):
#: (world, clips, frames per clip), 1920x1080 with a 4K camera's ground sampling.
ALTWORLD_SPLITS = (("sea", 12, 72), ("land", 12, 72))
VAL_SPLIT = ("maritime_val", 2, 60, "3840x2160")
#: Held-out validation: (world, clips, frames per clip), 1920x1080 frames with a 4K camera's
#: ground sampling; clip indices from :data:`HELDOUT_VAL_FIRST_CLIP` on.
HELDOUT_VAL = (("heldout_maritime", 2, 40), ("heldout_land", 2, 40))
#: Held-out clip indices below this are test clips (``tools/heldout_eval.py``).
HELDOUT_VAL_FIRST_CLIP = 100
#: Land people are scored as the maritime head's ``swimmer`` class (as tools/heldout_eval.py
#: scores them).
HELDOUT_RENAME = {"person": "swimmer"}
#: The land head's training presets (``--land-presets urban``): the simulator's people on land
#: (roads, roofs, cars, grass).
LAND_SPLITS = (("urban_train", 8, 60, "3840x2160"),)
#: ``--land-presets wild``: half of :data:`LAND_SPLITS` beside the wild land presets (meadow,
#: forest, rock, snow, sand) that the shipped maritime head learnt as ``swimmer``.
LAND_WILD_SPLITS = (("urban_train", 4, 60, "3840x2160"), *WILD_SPLITS)
#: ``--land-presets`` choice -> the land head's training presets.
LAND_PRESETS = {"urban": LAND_SPLITS, "wild": LAND_WILD_SPLITS}
#: The land head's validation: the held-out land world only, people as ``person``.
LAND_VAL = (("heldout_land", 3, 40),)
#: Settings of the land head beside :data:`TRAIN_ARGS`: fine-tuned from the maritime head.
LAND_ARGS = ["--classes", "person", "--lr", "0.002", "--epochs", "10", "--select-from", "1"]
#: Where the land head starts (left out by ``--from-scratch``): the maritime head, ``person``
#: from its ``swimmer`` row.
LAND_INIT_ARGS = ["--init", "default", "--init-class", "person=swimmer"]
#: The training seed of the shipped maritime head (the default ``--seed``): of the two seeds of
#: the wild recipe trained at full size, the one with the better validation F2 (0.298 against
#: 0.291; docs/generalisation_textures.md).
SHIPPED_SEED = 1
#: The training seed of the shipped land head's first part: of three seeds of ``--land-presets
#: wild``, the one with the best validation F2 (0.583 against 0.562 and 0.558; docs/land_head.md).
SHIPPED_LAND_SEED = 2
#: The training seed of its second part, the land recipe with the alternative world's land: the
#: seed the threshold was chosen with on validation clips (docs/land_head.md).
SHIPPED_LAND_ALTWORLD_SEED = 0
#: The weights of the two parts in the shipped land head's mean (docs/land_head.md).
SHIPPED_LAND_WEIGHTS = "3,1"
TRAIN_ARGS = [
    "--epochs",
    "30",
    "--batch-size",
    "64",
    "--lr",
    "0.02",
    "--seed",
    "0",
    "--frame-stride",
    "3",
    "--jitters",
    "4",
    "--ds",
    "1",
    "--select-from",
    "10",
    "--randomise",
    "all",
    "--background-negatives",
    "8",
]


def render(folder: Path, split: tuple[str, int, int, str]) -> Path:
    """Render one split ``(preset, clips, frames, WxH)`` into ``folder`` (skipped when its
    annotation file already exists)."""
    name, clips, frames, size = split
    annotations = folder / f"{name}.json"
    if not annotations.is_file():
        code = sarmission(
            [
                "sim",
                "generate",
                "--scenario",
                name,
                "--sequences",
                str(clips),
                "--frames",
                str(frames),
                "--out",
                str(folder),
                "--size",
                size,
            ]
        )
        if code:
            sys.exit(code)
    return annotations


def render_training_set(work: Path) -> Path:
    """Render every training preset into one folder and merge their annotations there."""
    folder = work / "maritime_train_mix"
    merged = folder / "maritime_train_mix.json"
    if not merged.is_file():
        parts = [read_coco_video(render(folder, split)) for split in TRAIN_SPLITS]
        write_coco_video(
            merge_datasets(parts, info={"presets": [s[0] for s in TRAIN_SPLITS]}), merged
        )
    return merged


def render_broad_training_set(work: Path, presets: str = "broad") -> Path:
    """The maritime training set plus the splits ``presets`` adds (:data:`EXTRA_SPLITS`),
    merged by category name (people on land as ``swimmer``) into
    ``work/<presets>_train_mix.json`` (``broad_train_mix.json``, ``broad_objects_...``)."""
    extra = EXTRA_SPLITS[presets]
    stem = "broad" if presets == "broad" else f"broad_{presets}"
    merged = work / f"{stem}_train_mix.json"
    if not merged.is_file():
        parts = [render_training_set(work)]
        parts += [render(work / split[0], split) for split in extra]
        names = [s[0] for s in TRAIN_SPLITS + extra]
        write_coco_video(
            merge_annotation_files(parts, HELDOUT_RENAME, info={"presets": names}), merged
        )
    return merged


def add_altworld(
    work: Path,
    train: Path,
    worlds: tuple[str, ...] = ("sea", "land"),
    rename: dict[str, str] | None = None,
) -> Path:
    """``train`` merged with the alternative world's clips of ``worlds``
    (:data:`ALTWORLD_SPLITS`, rendered into ``work/altworld`` unless there), people on land as
    ``swimmer`` unless ``rename`` says otherwise, into ``work/<train stem>_altworld.json``."""
    rename = HELDOUT_RENAME if rename is None else rename
    merged = work / f"{train.stem}_altworld.json"
    if merged.is_file():
        return merged
    parts = [train]
    for name, clips, frames in (s for s in ALTWORLD_SPLITS if s[0] in worlds):
        path = work / "altworld" / f"altworld_{name}.json"
        if not path.is_file():
            print(f"rendering altworld {name}: {clips} x {frames} frames", file=sys.stderr)
            render_altworld_world(name, clips, frames, path.parent)
        parts.append(path)
    info = {"train": train.name, "altworld": list(worlds)}
    write_coco_video(merge_annotation_files(parts, rename, info=info), merged)
    return merged


def heldout_val_seeds(splits: tuple[tuple[str, int, int], ...] = HELDOUT_VAL) -> list[int]:
    """Seeds of the held-out validation clips (a clip's seed is its world's seed * 1000 plus its
    index, :func:`heldout.presets.draw_clip`)."""
    return [
        world(name).seed * 1000 + HELDOUT_VAL_FIRST_CLIP + i
        for name, clips, _ in splits
        for i in range(clips)
    ]


def render_land_training_set(work: Path, presets: str = "urban") -> Path:
    """The land presets of ``presets`` (:data:`LAND_PRESETS`) rendered and merged into
    ``work/land_train_mix.json`` (``land_wild_train_mix.json`` for ``wild``)."""
    splits = LAND_PRESETS[presets]
    merged = work / (
        "land_train_mix.json" if presets == "urban" else f"land_{presets}_train_mix.json"
    )
    if not merged.is_file():
        parts = [render(work / split[0], split) for split in splits]
        write_coco_video(
            merge_annotation_files(parts, {}, info={"presets": [s[0] for s in splits]}),
            merged,
        )
    return merged


def heldout_val_missing(
    work: Path, splits: tuple[tuple[str, int, int], ...] = HELDOUT_VAL, name: str = "heldout_val"
) -> list[str]:
    """The worlds of ``splits`` whose validation clips :func:`render_heldout_val` would still
    have to render into ``work/<name>``."""
    folder = work / name
    if (folder / f"{name}.json").is_file():
        return []
    return [w for w, _, _ in splits if not (folder / w / f"{w}.json").is_file()]


def require_ffmpeg_for(
    work: Path, splits: tuple[tuple[str, int, int], ...] = HELDOUT_VAL, name: str = "heldout_val"
) -> None:
    """Stop with one line, before any work, when held-out validation clips (H.264) are still
    to be rendered and ffmpeg is missing."""
    missing = heldout_val_missing(work, splits, name)
    if not missing:
        return
    try:
        ffmpeg_path()
    except OSError as exc:
        raise SystemExit(
            f"held-out validation clips to render ({', '.join(missing)}): {exc}"
        ) from None


def render_heldout_val(
    work: Path,
    splits: tuple[tuple[str, int, int], ...] = HELDOUT_VAL,
    rename: dict[str, str] | None = None,
    name: str = "heldout_val",
) -> Path:
    """Render the held-out validation clips into ``work/<name>`` and merge them into one
    annotation file there (people on land as ``swimmer`` unless ``rename`` says otherwise);
    skipped when that file exists."""
    rename = HELDOUT_RENAME if rename is None else rename
    folder = work / name
    merged = folder / f"{name}.json"
    if not merged.is_file():
        require_ffmpeg_for(work, splits, name)
        parts = []
        for name, clips, frames in splits:
            path = folder / name / f"{name}.json"
            if not path.is_file():
                print(
                    f"rendering held-out validation {name}: {clips} x {frames} frames",
                    file=sys.stderr,
                )
                render_world(name, clips, frames, path.parent, first_clip=HELDOUT_VAL_FIRST_CLIP)
            parts.append(path)
        write_coco_video(
            merge_annotation_files(
                parts,
                rename,
                info={"worlds": [s[0] for s in splits], "first_clip": HELDOUT_VAL_FIRST_CLIP},
            ),
            merged,
        )
    return merged


def main() -> int:
    """Render, train, export and copy the default model into the package."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--work",
        type=Path,
        default=Path("/tmp/sarmission-default-model"),
        help="folder for the rendered data, crop caches and checkpoints",
    )
    parser.add_argument(
        "--val",
        choices=("sim", "heldout"),
        default="heldout",
        help="validation split that picks the epoch: held-out clips (the shipped head's "
        "recipe) or the simulator's maritime_val (default: heldout)",
    )
    parser.add_argument(
        "--presets",
        choices=tuple(EXTRA_SPLITS),
        default="wild",
        help="training presets: the maritime ones, those plus urban_train and the oblique "
        "maritime presets, or those plus maritime_objects_train or the wild land presets "
        "(the shipped head's recipe; default: wild), or the wild recipe plus "
        "maritime_floats_train or maritime_buoys_train (buoys_high: and "
        "maritime_buoys_high_train)",
    )
    parser.add_argument(
        "--altworld",
        action="store_true",
        help="add the alternative training world's clips (altworld/, its own renderer; "
        "docs/altworld.md) to the training set: sea and land for the maritime head, land for "
        "the land head",
    )
    parser.add_argument(
        "--no-install", action="store_true", help="do not copy the result into sarmission/models"
    )
    parser.add_argument(
        "--seed",
        type=int,
        default=None,
        help=f"training seed (default {SHIPPED_SEED} for the maritime head, "
        f"{SHIPPED_LAND_SEED} for the land head: the shipped heads'); seed 0 writes "
        "mitenet_head.pt, others mitenet_head_seed<N>.pt, so that several can be compared "
        "(presets other than wild add their name: mitenet_head_floats_seed<N>.pt)",
    )
    parser.add_argument(
        "--name",
        default=None,
        help="maritime head: the file name's stem in --work instead of the one the presets "
        "give (mitenet_head_buoys), so that variants of one recipe (other --classes or "
        "learning rates) do not overwrite each other; the seed is still added",
    )
    parser.add_argument(
        "--head",
        choices=("maritime", "land"),
        default="maritime",
        help="which shipped head to reproduce (default: maritime)",
    )
    parser.add_argument(
        "--land-presets",
        choices=tuple(LAND_PRESETS),
        default="wild",
        help="land head: half of the simulator's urban land beside the wild land presets "
        "(the shipped land head's recipe) or the urban land alone (default: wild)",
    )
    parser.add_argument(
        "--single",
        action="store_true",
        help="land head: the land recipe's head alone, not the mean of two (never installed)",
    )
    parser.add_argument(
        "--average-weights",
        default=None,
        help="land head: the weights of the land recipe's head and the head with the "
        f"alternative world's land in their mean (default {SHIPPED_LAND_WEIGHTS}, the shipped "
        "land head's)",
    )
    parser.add_argument(
        "--altworld-seed",
        type=int,
        default=SHIPPED_LAND_ALTWORLD_SEED,
        help="land head: the training seed of the head with the alternative world's land "
        f"(default {SHIPPED_LAND_ALTWORLD_SEED}, the shipped land head's)",
    )
    parser.add_argument(
        "--from-scratch",
        action="store_true",
        help="land head: start from random weights instead of the maritime head's",
    )
    args, extra = parser.parse_known_args()
    if args.seed is None:
        args.seed = SHIPPED_SEED if args.head == "maritime" else SHIPPED_LAND_SEED
    args.work.mkdir(parents=True, exist_ok=True)
    if args.head == "land":
        require_ffmpeg_for(args.work, LAND_VAL, "heldout_land_val")
        return train_land(args, extra)
    if args.val == "heldout":
        require_ffmpeg_for(args.work)
    train = (
        render_training_set(args.work)
        if args.presets == "maritime"
        else render_broad_training_set(args.work, args.presets)
    )
    if args.altworld:
        train = add_altworld(args.work, train)
    if args.val == "heldout":
        val = render_heldout_val(args.work)
    else:
        val = render(args.work / VAL_SPLIT[0], VAL_SPLIT)
    stem = "mitenet_head" + ("" if args.presets == "wild" else f"_{args.presets}")
    stem += "_altworld" if args.altworld else ""
    stem = args.name or stem
    out = args.work / (f"{stem}.pt" if args.seed == 0 else f"{stem}_seed{args.seed}.pt")
    code = train_head(train, val, out, [], args.seed, extra)
    if code:
        return code
    if not args.no_install:
        install(out, DEFAULT_TORCH_MODEL)
    return 0


def train_land(args: argparse.Namespace, extra: list[str]) -> int:
    """Render and train the land head into ``--work`` (module docstring): the weighted mean of
    the land recipe's head and the same recipe's with the alternative world's land, installed
    unless ``--no-install``; or one head alone (``--single``, ``--altworld``,
    ``--from-scratch``, ``--land-presets urban``), never installed."""
    single = args.single or args.altworld or args.from_scratch or args.land_presets != "wild"
    if not single:
        return train_land_average(args, extra)
    if args.average_weights is not None:
        print(
            "--average-weights needs the mean of two heads: leave out --single, "
            "--altworld, --from-scratch and --land-presets",
            file=sys.stderr,
        )
        return 2
    _, code = train_land_head(args, extra, args.altworld, args.seed)
    return code


def train_land_head(
    args: argparse.Namespace, extra: list[str], altworld: bool, seed: int, reuse: bool = False
) -> tuple[Path, int]:
    """Train one land head (``altworld``: with the alternative world's land) with ``seed``
    into ``--work`` (``reuse``: unless it is there, trained the same way); returns its
    checkpoint and the exit code."""
    train = render_land_training_set(args.work, args.land_presets)
    if altworld:  # its land only, people as the land head's ``person``
        train = add_altworld(args.work, train, ("land",), {})
    val = render_heldout_val(args.work, LAND_VAL, rename={}, name="heldout_land_val")
    stem = "mitenet_land_head" + ("_scratch" if args.from_scratch else "")
    stem += "" if args.land_presets == "urban" else f"_{args.land_presets}"
    stem += "_altworld" if altworld else ""
    stem += "" if seed == 0 else f"_seed{seed}"
    recipe = LAND_ARGS + ([] if args.from_scratch else LAND_INIT_ARGS)
    out = args.work / f"{stem}.pt"
    return out, train_head(train, val, out, recipe, seed, extra, reuse)


def train_land_average(args: argparse.Namespace, extra: list[str]) -> int:
    """The land head's mean (module docstring): the land recipe with ``--seed`` and the same
    recipe with the alternative world's land with ``--altworld-seed``, each trained unless
    ``--work`` holds it trained with the same options, averaged with ``--average-weights``
    and exported into ``--work``; installed unless ``--no-install``."""
    heads = []
    for altworld, seed in ((False, args.seed), (True, args.altworld_seed)):
        out, code = train_land_head(args, extra, altworld, seed, reuse=True)
        if code:
            return code
        heads.append(out)
    weights = args.average_weights or SHIPPED_LAND_WEIGHTS
    stem = f"mitenet_land_head_average_seed{args.seed}_alt{args.altworld_seed}"
    out = args.work / f"{stem}_w{weights.replace(',', '-')}.onnx"
    code = sarmission(
        ["export", "--average", *map(str, heads), "--weights", weights, "--out", str(out)]
    )
    if code or args.no_install:
        return code
    install(out.with_suffix(".pt"), shipped_checkpoint("land"))
    return 0


def install(trained: Path, shipped_pt: Path) -> None:
    """Copy a trained head's ``.pt`` and ``.onnx`` over the package's ``shipped_pt`` and its
    ``.onnx``."""
    shutil.copyfile(trained, shipped_pt)
    shutil.copyfile(trained.with_suffix(".onnx"), shipped_pt.with_suffix(".onnx"))
    onnx_name = shipped_pt.with_suffix(".onnx").name
    print(f"installed {shipped_pt.name} and {onnx_name} into {shipped_pt.parent}")


def train_command(
    train: Path, val: Path, out: Path, recipe: list[str], seed: int, extra: list[str]
) -> list[str]:
    """The ``sarmission train`` arguments: :data:`TRAIN_ARGS`, then ``recipe``, the seed and
    the user's own options (later ones win)."""
    return [
        "train",
        "--train",
        str(train),
        "--val",
        str(val),
        "--out",
        str(out),
        "--onnx",
        *TRAIN_ARGS,
        *recipe,
        "--seed",
        str(seed),
        *extra,
    ]


def training_record(command: list[str]) -> dict:
    """What a head trained by ``command`` was made from: the arguments and the SHA-256 of
    every input file they name (the annotation files and the heads it starts from or keeps
    the scores of, the shipped head for ``--init default`` or ``--keep-scores default``), so
    that a re-rendered training set or another starting head is not mistaken for the same
    training."""
    out = command[command.index("--out") + 1]
    files = [arg for arg in command if arg != out and Path(arg).is_file()]
    for flag in ("--init", "--keep-scores"):
        if flag in command and is_head_name(head := command[command.index(flag) + 1]):
            files.append(str(shipped_head_path(head, "torch")))
    digests = {name: hashlib.sha256(Path(name).read_bytes()).hexdigest() for name in files}
    return {"arguments": command, "inputs": digests}


def record_path(checkpoint: Path) -> Path:
    """Where :func:`train_head` keeps ``checkpoint``'s :func:`training_record`."""
    return checkpoint.with_suffix(".args.json")


def trained_with(checkpoint: Path) -> dict | None:
    """The record :func:`train_head` wrote beside ``checkpoint`` (:func:`training_record`),
    or None when there is no readable one (a head trained some other way)."""
    try:
        recorded = json.loads(record_path(checkpoint).read_text())
    except (OSError, ValueError):
        return None
    return recorded if isinstance(recorded, dict) else None


def train_head(
    train: Path,
    val: Path,
    out: Path,
    recipe: list[str],
    seed: int,
    extra: list[str],
    reuse: bool = False,
) -> int:
    """``sarmission train`` with :func:`train_command`'s arguments; writes ``out``, its ONNX
    and, once it is trained, its :func:`training_record` beside it (``.args.json``); returns
    the exit code. ``reuse``: keep ``out`` instead when its record is this training's."""
    command = train_command(train, val, out, recipe, seed, extra)
    record = training_record(command)
    if reuse and out.is_file():
        if trained_with(out) == record:
            print(f"reusing {out}")
            return 0
        print(f"retraining {out}: it was not trained with these options", file=sys.stderr)
    record_path(out).unlink(missing_ok=True)
    code = sarmission(command)
    if not code:
        record_path(out).write_text(json.dumps(record))
    return code


if __name__ == "__main__":
    sys.exit(main())
