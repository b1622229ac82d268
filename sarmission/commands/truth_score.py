"""Alerts scored against the simulator's ground truth: people found, geolocation error, false
alerts; the summary lines of ``demo`` and ``sim replay``."""

from __future__ import annotations

import math
from collections import Counter
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from sarmission.alerts.model import Alert

#: Alerts listed one by one in the summary (the rest are counted).
MAX_LISTED = 25
#: A detection is matched to the ground-truth person whose box centre is within this many px.
MATCH_PX = 24.0


def nearest(annotations: list[Any], cx: float, cy: float) -> Any:
    """The annotation whose box centre is nearest ``(cx, cy)`` within :data:`MATCH_PX`, or None."""
    best, best_d = None, MATCH_PX
    for a in annotations:
        x0, y0, x1, y1 = a.bbox_xyxy
        d = math.hypot((x0 + x1) / 2 - 0.5 - cx, (y0 + y1) / 2 - 0.5 - cy)
        if d <= best_d:
            best, best_d = a, d
    return best


def score(alerts: list[Alert], camera: Any, min_frames: int) -> list[str]:
    """Summary lines: people found vs in view, each alert's geolocation error, false alerts."""
    from sarmission.mission.targets import distance_m

    frames_seen: dict[int, int] = {}
    for frame in camera.truth:
        for a in frame.targets:
            frames_seen[a.track_id] = frames_seen.get(a.track_id, 0) + 1
    present = {tid for tid, n in frames_seen.items() if n >= min_frames}
    lines, found, errors, duplicates = [], set(), [], 0
    false_on: Counter[str] = Counter()
    for alert in alerts:
        cx, cy = alert.pixel_track[-1][1:] if alert.pixel_track else (math.nan, math.nan)
        best = nearest(camera.targets_at(alert.frame_index), cx, cy)
        if best is None:
            other = nearest(camera.others_at(alert.frame_index), cx, cy)
            on = other.category if other is not None else "open water"
            false_on[on] += 1
            lines.append(
                f"  target {alert.target_id}: FALSE ALERT ({alert.class_name} "
                f"{alert.score:.2f}, frame {alert.frame_index}, on {on})"
            )
            continue
        tag = ""
        if best.track_id in found:
            duplicates += 1
            tag = " (DUPLICATE of an earlier alert)"
        found.add(best.track_id)
        if alert.position is not None and best.lat is not None and best.lon is not None:
            err = distance_m(alert.position, (best.lat, best.lon))
            errors.append(err)
            where = f"geolocation error {err:.1f} m (estimated {alert.error_m:.1f} m)"
        else:
            where = f"no position: {alert.position_note}"
        lines.append(f"  target {alert.target_id}: {best.category} #{best.track_id}, {where}{tag}")
    head = [
        f"people in view (>= {min_frames} frames): {len(present)}, found: "
        f"{len(found & present)} of them"
        + (f" (+{len(found - present)} seen briefly)" if found - present else ""),
        f"alerts: {len(alerts)}, false alerts: {sum(false_on.values())}"
        + (
            " (on " + ", ".join(f"{what} {n}" for what, n in false_on.most_common()) + ")"
            if false_on
            else ""
        )
        + f", duplicates: {duplicates}",
    ]
    if errors:
        head.append(
            f"geolocation error: mean {sum(errors) / len(errors):.1f} m, "
            f"max {max(errors):.1f} m over {len(errors)} alerts"
        )
    if len(lines) > MAX_LISTED:
        lines = lines[:MAX_LISTED] + [f"  ... and {len(lines) - MAX_LISTED} more alerts"]
    return head + lines
