"""``sarmission train``: train the MITE-Net head on annotated videos (COCO video JSON).

Crops are cut once per annotation file and settings and cached; the checkpoint with the best
validation F2 is written to ``--out`` and the resume state to ``<out stem>.last.pt``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from sarmission.commands.cli_helpers import parse_pairs
from sarmission.commands.progress import add_progress_option, bars_wanted
from sarmission.perception.types import DEFAULT_COLOUR_SHARE, VALID_DS

_DEFAULT_CLASSES = "swimmer,swimmer_with_life_jacket"


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register the ``train`` sub-command."""
    parser = sub.add_parser(
        "train",
        help="train the MITE-Net head on annotated videos",
        description="Train the MITE-Net head: vSTMD + TTM-RPN crops of the annotated videos "
        "(cut once and cached), GT jittering, NWD label assignment, 1:3 hard negatives, "
        "BCE + NWD + DFL loss; keeps the checkpoint with the best validation F2.",
        formatter_class=argparse.ArgumentDefaultsHelpFormatter,
    )
    parser.add_argument("--train", required=True, type=Path, help="training annotations (JSON)")
    parser.add_argument("--val", required=True, type=Path, help="validation annotations (JSON)")
    parser.add_argument("--out", required=True, type=Path, help="best checkpoint (.pt) to write")
    parser.add_argument("--epochs", type=int, default=30)
    parser.add_argument("--batch-size", type=int, default=64)
    parser.add_argument("--lr", type=float, default=0.02, help="peak learning rate")
    parser.add_argument("--optimizer", choices=("sgd", "adamw"), default="sgd")
    parser.add_argument(
        "--select-from",
        type=int,
        default=1,
        help="first epoch whose head may be kept as the best checkpoint (default: %(default)s)",
    )
    parser.add_argument(
        "--ema-decay",
        type=float,
        default=0.0,
        help="validate and save a moving average of the weights with this decay "
        "per step, e.g. 0.999 (0 = the raw weights)",
    )
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument(
        "--ds",
        type=int,
        default=1,
        choices=VALID_DS,
        help="vSTMD down-sampling factor for the training crops",
    )
    parser.add_argument(
        "--frame-stride",
        type=int,
        default=5,
        help="cut crops at every k-th frame (all frames still go through vSTMD)",
    )
    parser.add_argument("--jitters", type=int, default=4, help="jittered copies per GT box")
    parser.add_argument(
        "--jitter-shift",
        type=float,
        default=0.5,
        help="largest centre shift of a jittered box per axis, as a fraction of "
        "its side (the RPN's boxes land up to about half a side off)",
    )
    parser.add_argument(
        "--motion-floor",
        type=float,
        default=0.0,
        help="temporal change (luma, 0-1) below which a crop's motion channel is not "
        "stretched to full scale; stored in the head (0 = per-crop max-abs, as in the paper)",
    )
    parser.add_argument(
        "--background-negatives",
        type=int,
        default=0,
        help="negatives cut per training frame at random places away from the "
        "targets (0 = only the RPN's proposals)",
    )
    parser.add_argument(
        "--object-negatives",
        type=int,
        default=0,
        help="negatives cut around every annotated object that is no search target "
        "(boats, debris, birds, glints), copies per object (0 = only the RPN's proposals)",
    )
    parser.add_argument(
        "--object-parts",
        action="store_true",
        help="label the RPN's proposals on part of a larger object of a head class (a boat "
        "of --classes maritime) with that class rather than as negatives",
    )
    parser.add_argument(
        "--object-context",
        type=int,
        default=0,
        help="wide crops (2-8 S) per target box larger than S, and as many of open background "
        "per frame, so that the wider --crop-scales of inference see a boat whole "
        "(0 = none)",
    )
    parser.add_argument(
        "--randomise",
        default="none",
        help="crop-level domain randomisation: comma-separated transforms of "
        "tone, white_balance, haze, hue, blur, noise, blocks, geometry; 'none', or 'all' "
        "(every one but haze), which may be followed by haze ('all,haze')",
    )
    parser.add_argument(
        "--randomise-p",
        type=float,
        default=0.5,
        help="share of the crops each randomisation transform changes",
    )
    parser.add_argument(
        "--texture-negatives",
        type=float,
        default=0.0,
        metavar="SHARE",
        help="procedural texture crops (dead leaves, fractal noise, stripes, edges) added to "
        "each batch as negatives, as a share of the batch size, e.g. 0.25 (default: none)",
    )
    parser.add_argument(
        "--texture-positives",
        type=float,
        default=0.0,
        metavar="SHARE",
        help="share of the positive crops whose surroundings are replaced by a procedural "
        "texture, e.g. 0.25 (default: none)",
    )
    parser.add_argument(
        "--rounding-consistency",
        type=float,
        default=0.0,
        metavar="WEIGHT",
        help="weight of a loss term that keeps the class scores of a crop and of its copy as "
        "another decoder would round it together, e.g. 1 (default: none)",
    )
    parser.add_argument(
        "--crop-norm",
        type=float,
        default=0.0,
        metavar="FLOOR",
        help="the head sees each crop's colour relative to the crop: its mean colour taken "
        "away, divided by its spread or FLOOR if more (RGB in [0, 1], e.g. 0.05; 1 centres "
        "only; default: 0, raw colour)",
    )
    parser.add_argument(
        "--still-share",
        type=float,
        default=0.0,
        metavar="SHARE",
        help="share of the crops given the motion channel of a background crop of their batch, "
        "as a still person under a hovering camera has none of their own, e.g. 0.3 "
        "(default: none)",
    )
    parser.add_argument("--topn", type=int, default=25, help="RPN proposals per frame (N)")
    parser.add_argument(
        "--colour-share",
        type=float,
        default=DEFAULT_COLOUR_SHARE,
        help="share of the proposals taken from colour anomalies (0 = motion "
        "only; default: %(default)s)",
    )
    parser.add_argument(
        "--pos-nwd", type=float, default=0.4, help="NWD at or above which a proposal is positive"
    )
    parser.add_argument(
        "--classes",
        default=_DEFAULT_CLASSES,
        help="comma-separated head classes (index = class id), or 'maritime': "
        "the swimmers, boats, jetskis, buoys and life-saving appliances "
        "of SeaDronesSee (classes that are no person are never alerted)",
    )
    parser.add_argument(
        "--cache-dir",
        type=Path,
        default=None,
        help="crop cache folder (default: <out folder>/.crop_cache)",
    )
    parser.add_argument(
        "--init",
        default=None,
        metavar="CHECKPOINT",
        help="start from a trained head's weights: a shipped head ('default' or "
        "'maritime', 'land') or a .pt file; classes both heads name keep their weights "
        "(fine-tuning on your own data)",
    )
    parser.add_argument(
        "--init-class",
        action="append",
        default=[],
        metavar="NEW=OLD",
        help="with --init: new class NEW starts from the trained head's class OLD "
        "(e.g. person=swimmer); repeatable",
    )
    parser.add_argument(
        "--keep-scores",
        default=None,
        metavar="CHECKPOINT",
        help="keep this trained head's person scores while learning other classes: a "
        "shipped head ('default', 'maritime', 'land') or a .pt file; its person "
        "probabilities on every crop not labelled one of the other classes are taught "
        "beside the labels (docs/datasets.md: on footage unlike the training set's the "
        "scores may still move)",
    )
    parser.add_argument(
        "--kept-scores-weight",
        type=float,
        default=4.0,
        help="weight of the kept person scores beside the head's own loss",
    )
    parser.add_argument(
        "--resume",
        action="store_true",
        help="continue from <out stem>.last.pt with the same settings",
    )
    parser.add_argument(
        "--onnx", action="store_true", help="also export the best checkpoint as ONNX next to --out"
    )
    parser.add_argument("--threads", type=int, default=2, help="torch CPU threads")
    add_progress_option(parser)
    parser.set_defaults(func=run)


def config_from_args(args: argparse.Namespace):
    """The :class:`~sarmission.training.train.TrainConfig` the arguments describe."""
    from sarmission.class_roles import MARITIME_CLASSES, normalise_class
    from sarmission.training.dataset import CropSettings
    from sarmission.training.randomise import Randomisation
    from sarmission.training.train import TrainConfig

    classes = (
        MARITIME_CLASSES
        if args.classes.strip() == "maritime"
        else tuple(c.strip() for c in args.classes.split(",") if c.strip())
    )
    if not classes:
        raise ValueError("--classes must name at least one class")
    names = [normalise_class(c) for c in classes]
    twice = sorted({c for c, n in zip(classes, names, strict=True) if names.count(n) > 1})
    if twice:  # two outputs for one class: its scores split between them
        raise ValueError(f"--classes names {', '.join(twice)} more than once")
    for flag, path in (("--train", args.train), ("--val", args.val)):
        if path.is_dir():
            raise ValueError(f"{flag} {path}: a folder; give its annotation file (.json)")
        if not path.is_file():
            raise FileNotFoundError(f"{flag} annotation file not found: {path}")
    if args.init_class and args.init is None:
        raise ValueError("--init-class needs --init (the head whose classes it names)")
    if args.init is not None:
        from sarmission.training.init_weights import init_path

        if not init_path(args.init).is_file():
            raise FileNotFoundError(f"--init checkpoint not found: {init_path(args.init)}")
    if args.keep_scores is not None:
        from sarmission.training.init_weights import init_path

        keeper = init_path(args.keep_scores, "--keep-scores")
        if not keeper.is_file():
            raise FileNotFoundError(f"--keep-scores checkpoint not found: {keeper}")
    if args.out.suffix.lower() not in (".pt", ".pth"):
        raise ValueError(f"--out must be a .pt or .pth file, got {args.out}")
    crops = CropSettings(
        classes=classes,
        ds=args.ds,
        topn=args.topn,
        colour_share=args.colour_share,
        frame_stride=args.frame_stride,
        pos_nwd=args.pos_nwd,
        jitters_per_gt=args.jitters,
        jitter_shift=args.jitter_shift,
        background_negatives=args.background_negatives,
        object_negatives=args.object_negatives,
        object_parts=args.object_parts,
        object_context=args.object_context,
        seed=args.seed,
        motion_floor=args.motion_floor,
    )
    return TrainConfig(
        train=args.train,
        val=args.val,
        out=args.out,
        epochs=args.epochs,
        batch_size=args.batch_size,
        lr=args.lr,
        optimizer=args.optimizer,
        select_from=args.select_from,
        ema_decay=args.ema_decay,
        seed=args.seed,
        crops=crops,
        randomise=Randomisation.parse(args.randomise, args.randomise_p),
        texture_negatives=args.texture_negatives,
        texture_positives=args.texture_positives,
        rounding_consistency=args.rounding_consistency,
        crop_norm=args.crop_norm,
        still_share=args.still_share,
        cache_dir=args.cache_dir,
        init=args.init,
        init_classes=parse_pairs(args.init_class, "--init-class"),
        keep_scores=args.keep_scores,
        kept_scores_weight=args.kept_scores_weight,
        resume=args.resume,
        num_threads=args.threads,
        progress=bars_wanted(args),
    )


def run(args: argparse.Namespace) -> int:
    """Train, then optionally export ONNX; prints the best epoch and F2."""
    from sarmission.training.train import train

    result = train(config_from_args(args))
    print(
        f"wrote {result.checkpoint}: best validation F2 {result.best_f2:.4f} at epoch "
        f"{result.best_epoch} ({result.train_crops} training / {result.val_crops} validation "
        f"crops); resume state {result.state}"
    )
    if args.onnx:
        from sarmission.perception.export import export_head_onnx

        print(export_head_onnx(result.checkpoint, result.checkpoint.with_suffix(".onnx")).summary())
    return 0
