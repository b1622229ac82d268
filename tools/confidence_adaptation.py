"""Would the operator's decisions make the alert confidence transfer? -> docs page.

    python tools/confidence_adaptation.py --model F.confidence.json [--record DEV.json]

A confidence model fitted on the simulator (``tools/fit_confidence.py``) is badly wrong on
held-out footage (docs/confidence.md): the share of people among confirmed alerts is the
scene's, not the simulator's. This study asks whether a mission could learn that share from
its operator. The model's linear predictor ``z`` of each confirmed alert is kept and only an
offset ``d`` is learnt per mission, ``p = sigmoid(z + d)``, with a normal prior of standard
deviation ``s`` on ``d`` and the operator's decisions on the mission's earlier alerts as
evidence; the confidence shown is the posterior mean of ``p`` with its 10-90 % range, as the
alert store rates it (:mod:`sarmission.alerts.operator_calibration`, the shipped code). The
operator is simulated as deciding each alert rightly, before the next one is confirmed, or
``lag`` alerts later.

Alerts: the held-out validation and test clips (:mod:`tools.heldout_alerts`' clips, replayed
with the model beside a copy of the shipped head; a split's sea clips, empty sea included, are
one mission, its land clips another) and the simulator's development flights (each flight a
mission; each confirmed candidate's ``z`` from a model fitted without its flight, as in
``tools/fit_confidence.py``). Printed and written: per source, the mean confidence and the
calibration error, fixed and adaptive; and for the shipped prior, how many alerts are shown with
a wide range (:data:`~sarmission.alerts.model.WIDE_RANGE`) and the calibration error of those
shown as one number.
"""

from __future__ import annotations

import argparse
import json
import math
import shlex
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
for folder in (ROOT, ROOT / "tools"):  # runnable from a checkout that is not installed
    if str(folder) not in sys.path:
        sys.path.insert(0, str(folder))

import fit_confidence  # noqa: E402
import heldout_alerts  # noqa: E402
from alert_suite import head_commit  # noqa: E402

from sarmission.alerts.model import WIDE_RANGE, is_wide  # noqa: E402
from sarmission.alerts.operator_calibration import (  # noqa: E402
    PRIOR_SD,
    OffsetBelief,
    Rating,
)
from sarmission.alerts.store import AlertStore  # noqa: E402
from sarmission.data.coco_video import read_coco_video  # noqa: E402
from sarmission.evaluation.alert_scoring import score_flight  # noqa: E402
from sarmission.evaluation.dataset_truth import dataset_truth  # noqa: E402
from sarmission.evaluation.reliability import PROBABILITY_EDGES, reliability_table  # noqa: E402
from sarmission.mission.confidence import confidence_beside, load_confidence  # noqa: E402
from sarmission.models import DEFAULT_ONNX_MODEL  # noqa: E402

DOC = ROOT / "docs" / "confidence_adaptation.md"
#: (prior standard deviation of the offset, operator's lag in alerts); s = 0: the fixed model.
VARIANTS = ((0.0, 0), (2.0, 0), (3.0, 0), (3.0, 3))

#: Per confirmed alert, in a mission: (clip, time) to order it by, its z, a person under it.
Mission = list[tuple[tuple[int, float], float, bool]]


def sigmoid(x: np.ndarray | float) -> np.ndarray | float:
    return 1.0 / (1.0 + np.exp(-x))


def held_out_missions(split: str, work: Path, model: Path, tmp: Path) -> list[Mission]:
    """The split's sea and land missions: each confirmed alert's ``z`` and truth."""
    heads = tmp / "heads"
    heads.mkdir(exist_ok=True)
    head = heads / DEFAULT_ONNX_MODEL.name
    shutil.copyfile(DEFAULT_ONNX_MODEL, head)
    shutil.copyfile(model, confidence_beside(head))
    first, _ = heldout_alerts.SPLITS[split]
    missions: dict[str, Mission] = {}
    for world in heldout_alerts.WORLDS:
        for index in range(first, first + 3):
            path = heldout_alerts.clip_path(work, world, index)
            dataset = read_coco_video(path)
            (video,) = dataset.videos
            db = tmp / f"{split}_{video.name}.db"
            cmd = heldout_alerts.replay_command(path, video, db, str(head), [])
            done = subprocess.run(cmd, cwd=ROOT, capture_output=True, text=True)
            if done.returncode != 0:
                raise SystemExit(f"{shlex.join(cmd)} failed:\n{done.stderr[-2000:]}")
            frames = dataset_truth(dataset, video.id, float(video.extra.get("fps", 30.0)))
            with AlertStore(db) as store:
                alerts = [a for a in store.list() if a.tier == "confirmed"]
            for alert in alerts:
                if alert.evidence_logit is None:
                    continue
                right = score_flight(frames, [(alert, alert.frame_index, 0.0)]).false_alerts == 0
                kind = "sea" if "maritime" in world else "land"
                missions.setdefault(kind, []).append(
                    ((index, alert.confirmed_at or alert.lock_time), alert.evidence_logit, right)
                )
    return list(missions.values())


def development_missions(record: dict) -> list[Mission]:
    """Each development flight's confirmed candidates, ``z`` from a model fitted without it."""
    data = fit_confidence.samples(record)
    classes = fit_confidence.head_classes()
    predicted = fit_confidence.leave_one_flight_out(
        data, classes, fit_confidence.weighted_classes(classes)
    )
    missions: dict[int, Mission] = {}
    for (flight, sightings, person, confirmed), p in zip(data, predicted, strict=True):
        if confirmed:
            order = (0, sightings[-1].t)
            missions.setdefault(flight, []).append((order, math.log(p / (1 - p)), person))
    return list(missions.values())


def rate(z: float, decided: list[tuple[float, bool]], prior_sd: float) -> Rating:
    """The confidence shown for ``z`` after the operator's ``decided`` (z, person) pairs;
    ``prior_sd`` 0: the fixed model."""
    if prior_sd == 0:
        p = float(sigmoid(z))
        return Rating(p, p, p)
    return OffsetBelief(decided, prior_sd).rate(z)


def judge(missions: list[Mission], prior_sd: float, lag: int) -> dict:
    ratings, truth = [], []
    for mission in missions:
        ordered = sorted(mission)
        for k, (_, z, person) in enumerate(ordered):
            decided = [(zi, yi) for _, zi, yi in ordered[: max(0, k - lag)]]
            ratings.append(rate(z, decided, prior_sd))
            truth.append(person)
    shown_p = [r.confidence for r in ratings]
    wide = [is_wide((r.low, r.high)) for r in ratings]
    narrow = [(p, y) for p, y, w in zip(shown_p, truth, wide, strict=True) if not w]
    return {
        "alerts": len(truth),
        "people": float(np.mean(truth)),
        "mean": float(np.mean(shown_p)),
        "ece": reliability_table(shown_p, truth, PROBABILITY_EDGES)["ece"],
        "wide": float(np.mean(wide)),
        "narrow_ece": (
            reliability_table([p for p, _ in narrow], [y for _, y in narrow], PROBABILITY_EDGES)[
                "ece"
            ]
            if narrow
            else None
        ),
    }


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--model", type=Path, required=True, help="a fitted .confidence.json")
    parser.add_argument("--record", type=Path, required=True, help="development flights' JSON")
    parser.add_argument("--work", type=Path, default=Path("/tmp/sarmission-heldout-alerts"))
    parser.add_argument("--doc", type=Path, default=DOC)
    args = parser.parse_args()
    load_confidence(args.model)  # one clear line when it cannot be used
    sources = {}
    with tempfile.TemporaryDirectory(prefix="sarmission-adaptation-") as tmp:
        for split in ("validation", "test"):
            heldout_alerts.render_clips(
                args.work,
                list(heldout_alerts.WORLDS),
                heldout_alerts.SPLITS[split][0],
                3,
                round(10.0 * heldout_alerts.FPS),
                2,
            )
            sources[f"held-out {split} clips"] = held_out_missions(
                split, args.work, args.model, Path(tmp)
            )
    sources["simulator development flights"] = development_missions(
        json.loads(args.record.read_text())
    )
    head = (
        "| alerts from | alerts | on a person | "
        + " | ".join(
            "fixed model"
            if s == 0
            else f"offset learnt, prior s {s:g}" + (f", {lag} late" if lag else "")
            for s, lag in VARIANTS
        )
        + " |"
    )
    lines = [head, "|" + "---|" * (3 + len(VARIANTS))]
    for name, missions in sources.items():
        results = [judge(missions, s, lag) for s, lag in VARIANTS]
        lines.append(
            f"| {name} | {results[0]['alerts']} | {100 * results[0]['people']:.0f} % | "
            + " | ".join(f"{100 * r['mean']:.0f} % / {r['ece']:.3f}" for r in results)
            + " |"
        )
    shipped = [(PRIOR_SD, 0), (PRIOR_SD, 3)]
    ranges = [
        "| alerts from | decided at once: shown as a range | calibration error of the rest | "
        "3 alerts late: shown as a range | calibration error of the rest |",
        "|---|---|---|---|---|",
    ]
    for name, missions in sources.items():
        cells = []
        for s, lag in shipped:
            r = judge(missions, s, lag)
            ece = "-" if r["narrow_ece"] is None else f"{r['narrow_ece']:.3f}"
            cells += [f"{100 * r['wide']:.0f} %", ece]
        ranges.append(f"| {name} | " + " | ".join(cells) + " |")
    print("\n".join(lines + [""] + ranges))
    command = "python tools/confidence_adaptation.py " + shlex.join(sys.argv[1:])
    page = [
        "# Would the operator's decisions make the alert confidence transfer?",
        "",
        f"Generated by `{command}` at {head_commit()} (`tools/confidence_adaptation.py`; its "
        "docstring says how). Each cell: the mean confidence shown / the calibration error "
        "over the confirmed alerts. The operator decides every alert rightly before the next "
        "is confirmed, or three alerts later; a held-out mission is three 10-second clips of "
        "one kind of world, so it holds few alerts to learn from.",
        "",
        *lines,
        "",
        f"With the shipped prior (standard deviation {PRIOR_SD:g}), an alert whose 10-90 % "
        f"range is {100 * WIDE_RANGE:.0f} points or wider is shown with its range "
        '("20 % likely a person, between 1 and 75 %"), so that a number that is not yet '
        "known is not read as one. How many were, and the calibration error of the alerts "
        "shown as one number:",
        "",
        *ranges,
        "",
    ]
    args.doc.write_text("\n".join(page))
    print(f"wrote {args.doc}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
