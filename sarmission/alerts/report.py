"""The post-flight report of a replay: one self-contained HTML page plus KML, GeoJSON and CSV.

``report.html`` needs nothing but itself (styles inline, thumbnails as data URIs, the map as
inline SVG from :mod:`~sarmission.alerts.report_map`): a team can open it offline or mail it.
It shows the facts of the run (footage, telemetry, alignment), the map of the flight track and
the alerts, a strip of alert cards (thumbnail, footage time, frame, pixel, position or why
there is none) and a summary table. ``alerts.kml`` and ``alerts.geojson`` come from
:mod:`~sarmission.alerts.export` (the GeoJSON with the track as a LineString feature beside
the alerts); ``alerts.csv`` has one row per alert. An alert without a position is never drawn
as a point: it says ``position unknown: <why>``.
"""

from __future__ import annotations

import base64
import csv
import html
import io
import json
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

from sarmission.alerts.export import alerts_geojson, alerts_kml
from sarmission.alerts.model import Alert, utc_iso
from sarmission.alerts.report_map import MapPoint, flight_map_svg

CSV_COLUMNS = (
    "short_id",
    "target_id",
    "tier",
    "class_name",
    "score",
    "confidence",
    "confidence_low",
    "confidence_high",
    "frame_index",
    "footage_time_s",
    "pixel_x",
    "pixel_y",
    "lock_time_utc",
    "lat",
    "lon",
    "error_m",
    "position_note",
    "alert_id",
)
_STYLE = """
body{font-family:system-ui,sans-serif;margin:24px;color:#222;background:#fff}
h1{font-size:22px;margin:0 0 12px} h2{font-size:17px;margin:22px 0 8px}
table{border-collapse:collapse;font-size:13px} td,th{border:1px solid #ccc;padding:3px 8px;
text-align:left;vertical-align:top} th{background:#eee}
.facts td:first-child{font-weight:bold;white-space:nowrap} .facts pre{margin:0;font-size:12px}
.strip{display:flex;flex-wrap:wrap;gap:10px}
.card{border:1px solid #bbb;border-radius:6px;padding:8px;width:190px;font-size:12px}
.card img{width:174px;height:174px;object-fit:contain;background:#000;display:block}
.card .none{width:174px;height:174px;background:#ddd;display:flex;align-items:center;
justify-content:center}
.card b{font-size:14px} .nopos{color:#a00}
"""


@dataclass
class ReportInput:
    """What a report shows: ``alerts``; the drone's ``track`` as ``(t, lat, lon)``;
    ``frame_times`` (frame index -> seconds into the footage); ``facts`` rows."""

    title: str
    alerts: list[Alert]
    track: list[tuple[float, float, float]] = field(default_factory=list)
    frame_times: dict[int, float] = field(default_factory=dict)
    facts: list[tuple[str, str]] = field(default_factory=list)


def _pixel(alert: Alert) -> tuple[float, float] | None:
    return (alert.pixel_track[-1][1], alert.pixel_track[-1][2]) if alert.pixel_track else None


def _where(alert: Alert) -> str:
    if alert.position is None:
        return f"position unknown: {_reason(alert.position_note)}"
    lat, lon = alert.position
    err = alert.format_error()
    return f"{lat:.6f}, {lon:.6f}" + (f" {err}" if err else "")


def _reason(note: str) -> str:
    return note or "no geolocation"


def _footage_time(alert: Alert, frame_times: dict[int, float]) -> float | None:
    return frame_times.get(alert.frame_index)


def _rows(report: ReportInput) -> list[dict[str, object]]:
    rows = []
    for a in report.alerts:
        px = _pixel(a)
        ft = _footage_time(a, report.frame_times)
        rows.append(
            {
                "short_id": a.short_id,
                "target_id": a.target_id,
                "tier": getattr(a, "tier", "confirmed"),
                "class_name": a.class_name,
                "score": f"{a.score:.3f}",
                "confidence": "" if a.confidence is None else f"{a.confidence:.3f}",
                **_confidence_range(a),
                "frame_index": a.frame_index,
                "footage_time_s": "" if ft is None else f"{ft:.3f}",
                "pixel_x": "" if px is None else f"{px[0]:.1f}",
                "pixel_y": "" if px is None else f"{px[1]:.1f}",
                "lock_time_utc": utc_iso(a.lock_time),
                "lat": "" if a.position is None else repr(a.position[0]),
                "lon": "" if a.position is None else repr(a.position[1]),
                "error_m": "" if a.error_m is None or a.position is None else f"{a.error_m:.2f}",
                "position_note": _where(a) if a.position is None else a.position_note,
                "alert_id": a.alert_id,
            }
        )
    return rows


def report_csv(report: ReportInput) -> str:
    """The CSV text: :data:`CSV_COLUMNS`, one row per alert."""
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=CSV_COLUMNS, lineterminator="\n")
    writer.writeheader()
    writer.writerows(_rows(report))
    return buf.getvalue()


def report_geojson(report: ReportInput) -> dict[str, object]:
    """The alerts' GeoJSON FeatureCollection with the flight track as a LineString."""
    doc = alerts_geojson(report.alerts)
    for feature in doc["features"]:
        props = feature["properties"]
        props.pop("thumbnail", None)
        for key, value in props.items():
            if isinstance(value, float):
                props[key] = finite_or_none(value)
    if len(report.track) > 1:
        doc["features"].append(
            {
                "type": "Feature",
                "id": "flight-track",
                "geometry": {
                    "type": "LineString",
                    "coordinates": [[lon, lat] for _, lat, lon in report.track],
                },
                "properties": {
                    "kind": "flight track",
                    "start_t": report.track[0][0],
                    "end_t": report.track[-1][0],
                },
            }
        )
    return doc


def _card(alert: Alert, frame_times: dict[int, float]) -> str:
    ft = _footage_time(alert, frame_times)
    px = _pixel(alert)
    img = (
        f'<img alt="thumbnail of {html.escape(alert.short_id)}" src="data:image/jpeg;base64,'
        f'{base64.b64encode(alert.thumbnail).decode()}">'
        if alert.thumbnail
        else '<div class="none">no thumbnail</div>'
    )
    where = html.escape(_where(alert))
    cls = "nopos" if alert.position is None else "pos"
    return (
        f'<div class="card" data-alert-id="{html.escape(alert.alert_id)}">{img}'
        f"<b>{html.escape(alert.short_id)}</b> {html.escape(alert.class_name)} "
        f"{html.escape(alert.format_score())}<br>"
        f"{'' if ft is None else f't = {ft:.2f} s, '}frame {alert.frame_index}"
        f"{'' if px is None else f', pixel {px[0]:.0f},{px[1]:.0f}'}<br>"
        f'<span class="{cls}">{where}</span></div>'
    )


def _confidence_range(alert: Alert) -> dict[str, str]:
    """The CSV's ``confidence_low`` and ``confidence_high`` (empty when unknown)."""
    bounds = getattr(alert, "confidence_range", None)
    if bounds is None:
        return {"confidence_low": "", "confidence_high": ""}
    return {"confidence_low": f"{bounds[0]:.3f}", "confidence_high": f"{bounds[1]:.3f}"}


def _table(rows: Sequence[dict[str, object]]) -> str:
    cols = (
        "short_id",
        "tier",
        "class_name",
        "score",
        "confidence",
        "footage_time_s",
        "frame_index",
        "pixel_x",
        "pixel_y",
        "lat",
        "lon",
        "error_m",
        "position_note",
    )
    head = "".join(f"<th>{c}</th>" for c in cols)
    body = "".join(
        "<tr>" + "".join(f"<td>{html.escape(str(r[c]))}</td>" for c in cols) + "</tr>" for r in rows
    )
    return f'<table class="summary"><tr>{head}</tr>{body}</table>'


def report_html(report: ReportInput) -> str:
    """The self-contained page (see the module docstring)."""
    placed = [a for a in report.alerts if a.position is not None]
    points = [MapPoint(a.short_id, a.position[0], a.position[1], a.error_m) for a in placed]
    svg = flight_map_svg([(lat, lon) for _, lat, lon in report.track], points)
    facts = "".join(
        f"<tr><td>{html.escape(k)}</td><td><pre>{html.escape(v)}</pre></td></tr>"
        for k, v in report.facts
    )
    unplaced = len(report.alerts) - len(placed)
    counts = f"{len(report.alerts)} alerts, {len(placed)} with a position" + (
        f", {unplaced} without" if unplaced else ""
    )
    cards = "".join(_card(a, report.frame_times) for a in report.alerts) or "<p>No alerts.</p>"
    return (
        '<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f"<title>{html.escape(report.title)}</title><style>{_STYLE}</style></head><body>"
        f'<h1>{html.escape(report.title)}</h1><p id="counts">{counts}</p>'
        f'<table class="facts">{facts}</table>'
        f'<h2>Map</h2>{svg}<h2>Alerts</h2><div class="strip">{cards}</div>'
        f"<h2>Summary</h2>{_table(_rows(report))}</body></html>\n"
    )


def write_report(out_dir: Path, report: ReportInput) -> list[Path]:
    """Write ``report.html``, ``alerts.kml``, ``alerts.geojson``, ``alerts.csv`` into
    ``out_dir`` (created); returns their paths."""
    out_dir.mkdir(parents=True, exist_ok=True)
    files = {
        "report.html": report_html(report).encode(),
        "alerts.kml": alerts_kml(report.alerts, name=report.title),
        "alerts.geojson": json.dumps(
            report_geojson(report), ensure_ascii=False, allow_nan=False
        ).encode(),
        "alerts.csv": report_csv(report).encode(),
    }
    paths = []
    for name, data in files.items():
        path = out_dir / name
        path.write_bytes(data)
        paths.append(path)
    return paths


def finite_or_none(value: float | None) -> float | None:
    """``value`` when it is a finite number, else None (for JSON without NaN)."""
    return value if value is not None and math.isfinite(value) else None
