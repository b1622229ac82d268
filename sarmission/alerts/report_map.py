"""An offline map of a flight as inline SVG: the drone's track, alerts with their error circles,
a scale bar, a north arrow and a lat/lon graticule. No tiles, no network: the report opens
anywhere, which is where search teams review footage.

Projection: equirectangular around the mean latitude (metres east/north of the centre), exact
enough for the few kilometres a search covers.
"""

from __future__ import annotations

import html
import math
from collections.abc import Sequence
from dataclasses import dataclass

_M_PER_DEG = 111_320.0


@dataclass(frozen=True)
class MapPoint:
    """An alert on the map: ``label`` (e.g. ``T3``), position, 1-sigma error (m), colour."""

    label: str
    lat: float
    lon: float
    error_m: float | None
    colour: str = "#d62728"


def _nice(x: float) -> float:
    """The largest 1, 2 or 5 times a power of ten not above ``x``."""
    if x <= 0:
        return 1.0
    p = 10 ** math.floor(math.log10(x))
    return max(m * p for m in (1, 2, 5) if m * p <= x)


def flight_map_svg(
    track: Sequence[tuple[float, float]],
    points: Sequence[MapPoint],
    width: int = 900,
    height: int = 560,
) -> str:
    """The map (an ``<svg>`` element) of ``track`` (``(lat, lon)``) and ``points``."""
    lats = [p[0] for p in track] + [p.lat for p in points]
    lons = [p[1] for p in track] + [p.lon for p in points]
    if not lats:
        return (
            f'<svg class="map" xmlns="http://www.w3.org/2000/svg" width="{width}" '
            f'height="120" role="img"><text x="20" y="60" font-size="16">No positions to '
            "map: no telemetry placed the drone or any alert.</text></svg>"
        )
    lat0 = (min(lats) + max(lats)) / 2
    lon0 = (min(lons) + max(lons)) / 2
    kx = _M_PER_DEG * math.cos(math.radians(lat0))

    def metres(lat: float, lon: float) -> tuple[float, float]:
        return (lon - lon0) * kx, (lat - lat0) * _M_PER_DEG

    xs, ys = zip(*(metres(a, o) for a, o in zip(lats, lons, strict=True)), strict=True)
    pad = 40.0
    span = max(max(xs) - min(xs), max(ys) - min(ys), 50.0) * 1.15
    scale = min((width - 2 * pad) / span, (height - 2 * pad) / span)

    def px(lat: float, lon: float) -> tuple[float, float]:
        x, y = metres(lat, lon)
        return width / 2 + x * scale, height / 2 - y * scale

    out = [
        f'<svg class="map" xmlns="http://www.w3.org/2000/svg" width="{width}" '
        f'height="{height}" viewBox="0 0 {width} {height}" role="img" '
        'aria-label="map of the flight track and alerts">',
        f'<rect width="{width}" height="{height}" fill="#f4f1e8"/>',
    ]
    out += _graticule(lat0, lon0, kx, scale, width, height)
    if len(track) > 1:
        path = " ".join(f"{x:.1f},{y:.1f}" for x, y in (px(a, o) for a, o in track))
        out.append(
            f'<polyline class="track" points="{path}" fill="none" stroke="#1f77b4" '
            'stroke-width="2" stroke-linejoin="round"/>'
        )
    if track:
        for (a, o), name, fill in ((track[0], "start", "#2ca02c"), (track[-1], "end", "#555")):
            x, y = px(a, o)
            out.append(
                f'<g class="{name}"><rect x="{x - 5:.1f}" y="{y - 5:.1f}" width="10" '
                f'height="10" fill="{fill}"/><text x="{x + 8:.1f}" y="{y + 4:.1f}" '
                f'font-size="12">{name}</text></g>'
            )
    for p in points:
        x, y = px(p.lat, p.lon)
        if p.error_m is not None and math.isfinite(p.error_m):
            r = max(p.error_m * scale, 2.0)
            out.append(
                f'<circle cx="{x:.1f}" cy="{y:.1f}" r="{r:.1f}" fill="{p.colour}" '
                'fill-opacity="0.15" stroke="none"/>'
            )
        out.append(
            f'<g class="alert-marker"><circle cx="{x:.1f}" cy="{y:.1f}" r="6" '
            f'fill="{p.colour}" stroke="white" stroke-width="1.5"/>'
            f'<text x="{x + 9:.1f}" y="{y - 7:.1f}" font-size="13" font-weight="bold">'
            f"{html.escape(p.label)}</text></g>"
        )
    out += _scale_bar(scale, height)
    out.append(
        f'<g class="north"><path d="M{width - 30},{pad + 30} l8,10 h-16 z" fill="#333"/>'
        f'<text x="{width - 34}" y="{pad + 22}" font-size="14">N</text></g>'
    )
    out.append("</svg>")
    return "\n".join(out)


def _graticule(
    lat0: float, lon0: float, kx: float, scale: float, width: int, height: int
) -> list[str]:
    half_w, half_h = width / 2 / scale, height / 2 / scale
    step_lat = _nice(2 * half_h / _M_PER_DEG / 3)
    step_lon = _nice(2 * half_w / kx / 3)
    digits = max(0, -math.floor(math.log10(min(step_lat, step_lon))))
    out = ['<g class="graticule" stroke="#ccc" stroke-width="0.8" font-size="10" fill="#777">']
    lat = math.floor((lat0 - half_h / _M_PER_DEG) / step_lat) * step_lat
    while lat <= lat0 + half_h / _M_PER_DEG:
        y = height / 2 - (lat - lat0) * _M_PER_DEG * scale
        out.append(
            f'<line x1="0" y1="{y:.1f}" x2="{width}" y2="{y:.1f}"/>'
            f'<text x="3" y="{y - 2:.1f}" stroke="none">{lat:.{digits}f}</text>'
        )
        lat += step_lat
    lon = math.floor((lon0 - half_w / kx) / step_lon) * step_lon
    while lon <= lon0 + half_w / kx:
        x = width / 2 + (lon - lon0) * kx * scale
        out.append(
            f'<line x1="{x:.1f}" y1="0" x2="{x:.1f}" y2="{height}"/>'
            f'<text x="{x + 2:.1f}" y="{height - 3}" stroke="none">{lon:.{digits}f}'
            "</text>"
        )
        lon += step_lon
    out.append("</g>")
    return out


def _scale_bar(scale: float, height: int) -> list[str]:
    metres = _nice(150.0 / scale)
    length = metres * scale
    label = f"{metres / 1000:g} km" if metres >= 1000 else f"{metres:g} m"
    y = height - 20
    return [
        f'<g class="scale"><rect x="18" y="{y - 16}" width="{length + 16:.1f}" height="26" '
        f'fill="white" fill-opacity="0.8"/><line x1="26" y1="{y}" x2="{26 + length:.1f}" '
        f'y2="{y}" stroke="#000" stroke-width="3"/><text x="26" y="{y - 5}" '
        f'font-size="12">{label}</text></g>'
    ]
