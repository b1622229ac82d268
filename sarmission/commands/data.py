"""``sarmission data import``: published drone datasets into the project's COCO-video format.

The written file trains (``sarmission train --train FILE.json --init default``), evaluates
(``sarmission eval``) and replays like the simulator's output; image paths in it are absolute,
so it may be written anywhere. docs/datasets.md lists each dataset's source, licence and layout.
"""

from __future__ import annotations

import argparse
from collections import Counter
from pathlib import Path

from sarmission.commands.progress import add_progress_option, bars_wanted
from sarmission.data.importers import IMPORTERS


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``data`` and its sub-commands."""
    parser = sub.add_parser(
        "data",
        help="import published drone datasets (SeaDronesSee, LADD, VisDrone, HERIDAL, TinyPerson)",
        description="Datasets: convert a published dataset into the project's COCO-video format.",
    )
    data_sub = parser.add_subparsers(dest="data_command", metavar="DATA_COMMAND", required=True)
    imp = data_sub.add_parser(
        "import",
        help="convert a dataset folder into one COCO-video annotation file",
        description="Read a dataset in its published layout and write the project's COCO-video "
        "file: categories as the project names them (person, swimmer, boat ...), ignore regions "
        "as iscrowd, videos where the dataset has them, per-image telemetry where it has it "
        "(SeaDronesSee), absolute image paths.",
    )
    imp.add_argument("format", choices=tuple(IMPORTERS), help="the dataset's format")
    imp.add_argument("source", type=Path, help="the dataset's folder (or annotation file)")
    imp.add_argument("--out", required=True, type=Path, help="COCO-video JSON file to write")
    imp.add_argument("--split", default=None, help="one split only, e.g. train, val, test")
    add_progress_option(imp)
    imp.set_defaults(func=run_import)


#: Names of the annotation files the importers read (SeaDronesSee, TinyPerson, VOC XML,
#: VisDrone text): an import's ``--out`` under the source folder may not be one of them.
ANNOTATION_PATTERNS = ("instances_*.json", "tiny_set_*.json", "*.xml", "*.txt")


def check_import_output(source: Path, out: Path) -> None:
    """ValueError for an ``--out`` that is a folder, or an existing file the import reads (the
    source file itself, or an annotation file under the source folder): an import never
    writes over what it reads. An earlier import's output there may be written again."""
    if out.is_dir():
        raise ValueError(f"--out {out}: a folder; give the JSON file to write")
    if not out.exists():
        return
    target, root = out.resolve(), source.resolve()
    read = root.is_dir() and root in target.parents
    if target == root or (read and any(target.match(p) for p in ANNOTATION_PATTERNS)):
        raise ValueError(
            f"--out {out}: a file of the dataset being imported ({source}); "
            "write the import elsewhere"
        )


def run_import(args: argparse.Namespace) -> int:
    """Import, write, and print what the file holds."""
    from sarmission.data.coco_video import write_coco_video
    from sarmission.data.importers import import_dataset

    if not args.source.exists():
        raise FileNotFoundError(f"{args.source}: no such file or folder")
    check_import_output(args.source, args.out)
    dataset = import_dataset(args.format, args.source, args.split, progress=bars_wanted(args))
    args.out.parent.mkdir(parents=True, exist_ok=True)
    write_coco_video(dataset, args.out)
    names = {c.id: c.name for c in dataset.categories}
    boxes = Counter(names[a.category_id] for a in dataset.annotations if not a.iscrowd)
    ignored = sum(1 for a in dataset.annotations if a.iscrowd)
    with_meta = sum(1 for im in dataset.images if not im.telemetry.is_empty())
    print(f"wrote {args.out}: {len(dataset.images)} images in {len(dataset.videos)} videos")
    listed = ", ".join(f"{count} {name}" for name, count in boxes.most_common())
    print(f"boxes: {listed or 'none'}")
    print(f"ignore regions: {ignored}; images with telemetry: {with_meta}")
    if dataset.info.get("images_not_found"):
        print(f"image files not found (paths kept): {dataset.info['images_not_found']}")
    for reason, count in dataset.info.get("skipped", {}).items():
        print(f"skipped: {count} ({reason})")
    return 0
