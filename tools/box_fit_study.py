"""Detection boxes as the head gives them and fitted to the object, frame level, written to
docs/box_fit.md.

The head boxes what its 16 x 16 crop shows: a person lying 30-50 px long gets a torso-sized
box, which the report's match (NWD 0.5) counts as a miss. ``MiteNet(fit_boxes=True)`` replaces
each box by the object's extent against its surroundings
(:func:`sarmission.perception.extent.fit_boxes`). This tool runs the detector with and without
it, side by side, on the held-out generator's clips (``tools/heldout_alerts.py``'s validation
and test clips, rendered when missing) and the simulator's ``maritime_test`` (as
``tools/heldout_eval.py`` renders it), and reports SSR at NWD 0.5 (the report's), 0.3 and 0.1
(how much of a miss is the box alone), FAR per detection, how many boxes were fitted and the
fitting's cost per frame. The maritime head has no ``person`` class: on land it is scored with
people as ``swimmer``, as ``tools/heldout_eval.py`` does. Measured numbers are kept as JSON
(``<work>/box_fit_results.json``); the Markdown is a pure function of it::

    nice -n 19 python tools/box_fit_study.py [--splits validation,test] [--clips 6]
    python tools/box_fit_study.py --from-json /tmp/sarmission-heldout-alerts/box_fit_results.json
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
import time
from collections.abc import Iterator
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tools"))

from heldout_alerts import SPLITS, clip_path, render_clips  # noqa: E402
from heldout_eval import persons_as_swimmers, render_own  # noqa: E402

from sarmission.data.coco_video import read_coco_video  # noqa: E402
from sarmission.evaluation.matching import FrameBoxes, match_frame  # noqa: E402
from sarmission.evaluation.report import person_category_map  # noqa: E402
from sarmission.evaluation.run_model import ModelRun, run_mitenet  # noqa: E402
from sarmission.evaluation.sar_metrics import evaluate_sar, sequences_from_dataset  # noqa: E402
from sarmission.perception.mitenet import MiteNet, build_head_runtime  # noqa: E402

OUT = ROOT / "docs" / "box_fit.md"
#: The match thresholds reported: the report's (0.5) and two looser ones.
NWD_THRESHOLDS = (0.5, 0.3, 0.1)
#: Frames per held-out clip (10 s at 30 frames/s), as tools/heldout_alerts.py renders them.
CLIP_FRAMES = 300
#: (world, head) pairs: each held-out world with the head its mission runs, and the land world
#: with the default (maritime) head too, as the held-out flights fly it.
CASES = (
    ("heldout_maritime", "maritime"),
    ("heldout_land", "land"),
    ("heldout_land", "maritime"),
)


@dataclass
class Outcome:
    """One configuration over one set of clips."""

    ssr: dict[str, tuple[float | None, int, int]]  # NWD threshold -> (SSR %, locked, lockable)
    far_detections: float | None  # at the report's NWD 0.5
    detections: int
    fitted: int
    frame_ms: float
    fit_ms: float
    # FAR per detection at each NWD threshold, and the detections that match a person at NWD
    # 0.1 but not 0.5 (:func:`near_misses`); None in results measured before they were kept
    far_by_nwd: dict[str, float | None] | None = None
    near: dict[str, float] | None = None


def _sequences(runs: list[tuple[object, ModelRun]], classes: tuple[str, ...]) -> dict:
    sequences = {}
    for index, (dataset, run) in enumerate(runs):
        cats = list(person_category_map(dataset.categories, classes))
        dets = {i: FrameBoxes.of(d.boxes, d.scores, d.class_ids) for i, d in run.detections.items()}
        for name, frames in sequences_from_dataset(dataset, dets, cats).items():
            sequences[f"{index}:{name}"] = frames
    return sequences


def near_misses(sequences: dict) -> dict[str, float]:
    """The detections (score > 0.5) matched one-to-one to a person at NWD 0.1 but not at 0.5:
    how many, and how their box's longer side compares with the person's (``ratio_p25/50/75``;
    ``short``: under 0.8 of it, ``long``: over 1.25, with the people's median side in px)."""
    ratios, sides = [], []
    for frames in sequences.values():
        for frame in frames:
            strict = match_frame(frame.detections, frame.ground_truth, nwd_thr=0.5)
            loose = match_frame(frame.detections, frame.ground_truth, nwd_thr=0.1)
            matched = set(strict.det_indices.tolist())
            for det, gt in zip(loose.det_indices, loose.gt_indices, strict=True):
                if det in matched:
                    continue
                box, truth = frame.detections.boxes[det], frame.ground_truth.boxes[gt]
                side = max(truth[2] - truth[0], truth[3] - truth[1])
                ratios.append(max(box[2] - box[0], box[3] - box[1]) / side)
                sides.append(side)
    if not ratios:
        return {"n": 0}
    ratio, side = np.asarray(ratios), np.asarray(sides)
    short, long = ratio < 0.8, ratio > 1.25
    p25, p50, p75 = np.percentile(ratio, [25, 50, 75])
    return {
        "n": len(ratio),
        "short": float(short.mean()),
        "short_side_px": float(np.median(side[short])) if short.any() else float("nan"),
        "long": float(long.mean()),
        "long_side_px": float(np.median(side[long])) if long.any() else float("nan"),
        "ratio_p25": float(p25),
        "ratio_p50": float(p50),
        "ratio_p75": float(p75),
    }


def _fitted(plain: ModelRun, fitted: ModelRun) -> tuple[int, int]:
    """(detections, of which the box differs) over the two runs' frames."""
    total = changed = 0
    for image_id, boxes in plain.detections.items():
        other = fitted.detections[image_id]
        total += len(boxes.boxes)
        changed += int(np.any(boxes.boxes != other.boxes, axis=1).sum())
    return total, changed


def _has_people(path: Path) -> bool:
    """Whether any annotation of the file is of the ``person`` category (the land world's; the
    sea world names the category too, and annotates swimmers)."""
    doc = json.loads(path.read_text(encoding="utf-8"))
    person = {category["id"] for category in doc["categories"] if category["name"] == "person"}
    return any(annotation["category_id"] in person for annotation in doc["annotations"])


def measure(paths: list[Path], model: str) -> dict[bool, Outcome]:
    """The detector (ds 2, N 25, the defaults) with and without fitting on every clip."""
    head = build_head_runtime(None if model == "maritime" else model, "onnx")
    if "person" not in head.classes:  # land people scored as swimmers; sea clips as they are
        paths = [persons_as_swimmers(path) if _has_people(path) else path for path in paths]
    datasets = [read_coco_video(path) for path in paths]
    runs: dict[bool, list[tuple[object, ModelRun]]] = {False: [], True: []}
    for dataset in datasets:
        for fit in (False, True):  # side by side, clip by clip: the timings share conditions
            net = MiteNet(head, fit_boxes=fit)
            runs[fit].append((dataset, run_mitenet(net, dataset, progress=False)))
    total = changed = 0
    for (_, plain), (_, fitted) in zip(runs[False], runs[True], strict=True):
        t, c = _fitted(plain, fitted)
        total, changed = total + t, changed + c
    outcomes = {}
    for fit, pairs in runs.items():
        sequences = _sequences(pairs, head.classes)
        ssr, far = {}, {}
        for threshold in NWD_THRESHOLDS:
            metrics = evaluate_sar(sequences, nwd_thr=threshold)
            locked, lockable = metrics.n_locked, metrics.n_lockable
            ssr[f"{threshold:g}"] = (metrics.search_success_rate, locked, lockable)
            far[threshold] = metrics.false_alarm_rate_detections
        outcomes[fit] = Outcome(
            ssr=ssr,
            far_detections=far[0.5],
            detections=total,
            fitted=changed if fit else 0,
            frame_ms=statistics.median(ms for _, run in pairs for ms in run.frame_ms),
            fit_ms=statistics.median(ms for _, run in pairs for ms in run.stage_ms.get("fit", [0])),
            far_by_nwd={f"{t:g}": far[t] for t in NWD_THRESHOLDS},
            near=near_misses(sequences),
        )
    return outcomes


def _percent(value: float | None) -> str:
    return "-" if value is None else f"{value:.1f} %"


def _labelled(rows: list[tuple[str, dict[bool, Outcome]]]) -> Iterator[tuple[str, bool, Outcome]]:
    """``(footage | head | boxes cells, fitted?, outcome)`` of every outcome of ``rows``."""
    for label, outcomes in rows:
        footage, head = label.split(" | ")
        for fit, outcome in outcomes.items():
            yield f"{footage} | {head} | {'fitted' if fit else 'head'}", fit, outcome


def table(rows: list[tuple[str, dict[bool, Outcome]]]) -> list[str]:
    lines = [
        "| footage | head | boxes | SSR NWD 0.5 | SSR NWD 0.3 | SSR NWD 0.1 | FAR/det | "
        "fitted | ms/frame | fitting ms/frame |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for cells, fit, o in _labelled(rows):
        ssr = [
            f"{_percent(o.ssr[f'{t:g}'][0])} ({o.ssr[f'{t:g}'][1]}/{o.ssr[f'{t:g}'][2]})"
            for t in NWD_THRESHOLDS
        ]
        share = f"{100 * o.fitted / o.detections:.0f} %" if fit and o.detections else "-"
        fit_ms = f"{o.fit_ms:.2f}" if fit else "-"
        lines.append(
            f"| {cells} | {' | '.join(ssr)} | "
            f"{_percent(o.far_detections)} | {share} | {o.frame_ms:.1f} | {fit_ms} |"
        )
    return lines


def _share(share: float, side_px: float) -> str:
    return f"{100 * share:.0f} % ({side_px:.0f} px)" if share else "0 %"


def near_table(rows: list[tuple[str, dict[bool, Outcome]]]) -> list[str]:
    """Where the boxes still miss: FAR at each NWD threshold and the near misses' sizes."""
    lines = [
        "| footage | head | boxes | FAR/det NWD 0.5 / 0.3 / 0.1 | near misses | box under 0.8 x "
        "the person (their side p50) | box over 1.25 x (their side p50) | box / person p25 / "
        "p50 / p75 |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for cells, _, o in _labelled(rows):
        if o.far_by_nwd is None or o.near is None:
            continue
        far = " / ".join(_percent(o.far_by_nwd[f"{t:g}"]) for t in NWD_THRESHOLDS)
        near = o.near
        if not near["n"]:
            sizes = "- | - | -"
        else:
            sizes = (
                f"{_share(near['short'], near['short_side_px'])} | "
                f"{_share(near['long'], near['long_side_px'])} | "
                f"{near['ratio_p25']:.2f} / {near['ratio_p50']:.2f} / {near['ratio_p75']:.2f}"
            )
        lines.append(f"| {cells} | {far} | {near['n']:.0f} | {sizes} |")
    return lines if len(lines) > 2 else []


def render(results: dict) -> str:
    """docs/box_fit.md from the results JSON."""
    rows = [
        (row["label"], {fit == "fitted": Outcome(**o) for fit, o in row["outcomes"].items()})
        for row in results["rows"]
    ]
    lines = [
        "# Boxes fitted to the object",
        "",
        f"Generated by `{results['command']}` (`tools/box_fit_study.py`, "
        f"{results['minutes']:.1f} min, at {results['commit']}). The head boxes what its 16 x 16 "
        "crop shows, so a person lying 30-50 px long gets a box of their torso, which the "
        "report's match (NWD 0.5) counts as a miss. With `[detector] fit_boxes` the box of "
        "each detection scored at least 0.5 (the 8 best-scored of a frame; lower scores never "
        "count towards a lock) becomes the object's extent against its surroundings "
        "(`sarmission.perception.extent.fit_boxes`) where that is longer than the head's box, "
        "holds its centre and is at most 4 S (64 px) long; scores and classes stay the head's. "
        "The detector at ds 2, N 25 and every other default, run with the head's boxes and "
        "with fitted ones, clip by clip side by side. Held-out clips: the generator that "
        "shares no code with the simulator (`heldout/`), 10 s at 30 frames/s, 1080p; the "
        "maritime head scores land people as `swimmer`. SSR: locked of lockable "
        "trajectories, matched at the NWD threshold shown. *Fitted*: the share of detections "
        "whose box changed. *ms/frame*: the whole detector's median, *fitting ms*: the "
        "fitting stage's median (`per_stage_ms['fit']`), on this machine's CPU, from one "
        "pass each: the speed figure is `python tools/fit_cost.py`, fitting on and off side "
        "by side in one process (docs/experiments.md).",
        "",
        *table(rows),
        "",
    ]
    near = near_table(rows)
    if near:
        lines += [
            "## Where the boxes still miss",
            "",
            "FAR per detection at each match threshold: a detection on a person whose box is "
            "too far off to match at NWD 0.5 counts as false there. *Near misses*: detections "
            "scored above 0.5 that match a person one-to-one at NWD 0.1 but not at 0.5, over "
            "every frame; their box's longer side against the person's.",
            "",
            *near,
            "",
        ]
    return "\n".join(lines)


def measure_all(args: argparse.Namespace) -> dict:
    """Every row, as the results JSON holds it."""
    started = time.monotonic()
    worlds = sorted({world for world, _ in CASES})
    rows: list[tuple[str, dict[bool, Outcome]]] = []
    own = render_own(args.own_work, args.own_sequences, args.own_frames, [])
    rows.append(("`maritime_test` (own renderer, 4K) | maritime", measure([own], "maritime")))
    print("maritime_test: done", file=sys.stderr, flush=True)
    for split in args.splits:
        first = SPLITS[split][0]
        render_clips(args.work, worlds, first, args.clips, CLIP_FRAMES, args.jobs)
        last = first + args.clips - 1
        for world, model in CASES:
            paths = [clip_path(args.work, world, first + i) for i in range(args.clips)]
            label = f"`{world}` {split} {first}-{last} | {model}"
            rows.append((label, measure(paths, model)))
            print(f"{label}: done", file=sys.stderr, flush=True)
    commit = subprocess.run(
        ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, cwd=ROOT
    ).stdout.strip()
    return {
        "command": (
            f"nice -n 19 python tools/box_fit_study.py --splits {','.join(args.splits)} "
            f"--clips {args.clips} --own-sequences {args.own_sequences} "
            f"--own-frames {args.own_frames}"
        ),
        "commit": commit or "?",
        "minutes": (time.monotonic() - started) / 60,
        "rows": [
            {
                "label": label,
                "outcomes": {("fitted" if fit else "head"): asdict(o) for fit, o in out.items()},
            }
            for label, out in rows
        ],
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--splits",
        type=lambda text: [part for part in text.split(",") if part],
        default=["validation", "test"],
        help=f"held-out clip splits, comma-separated: {', '.join(sorted(SPLITS))}",
    )
    parser.add_argument("--clips", type=int, default=6, help="held-out clips per world")
    parser.add_argument("--own-sequences", type=int, default=2, help="clips of maritime_test")
    parser.add_argument("--own-frames", type=int, default=40, help="frames per maritime_test clip")
    parser.add_argument("--work", type=Path, default=Path("/tmp/sarmission-heldout-alerts"))
    parser.add_argument("--own-work", type=Path, default=Path("/tmp/sarmission-heldout"))
    parser.add_argument("--jobs", type=int, default=2, help="clips rendered at once")
    parser.add_argument("--out", type=Path, default=OUT)
    parser.add_argument(
        "--from-json", type=Path, default=None, help="re-render the Markdown, measuring nothing"
    )
    args = parser.parse_args()
    unknown = sorted(set(args.splits) - set(SPLITS))
    if unknown or not args.splits:
        parser.error(f"--splits: expected some of {', '.join(sorted(SPLITS))}, got {unknown}")
    if min(args.clips, args.own_sequences, args.own_frames) < 1:
        parser.error("--clips, --own-sequences and --own-frames must be at least 1")
    if args.from_json is not None:
        try:
            results = json.loads(args.from_json.read_text(encoding="utf-8"))
        except (OSError, ValueError) as exc:
            parser.error(f"--from-json {args.from_json}: {exc}")
    else:
        results = measure_all(args)
        saved = args.work / "box_fit_results.json"
        saved.write_text(json.dumps(results, indent=1), encoding="utf-8")
        print(f"wrote {saved}", file=sys.stderr)
    args.out.write_text(render(results), encoding="utf-8")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
