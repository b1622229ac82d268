"""Alerts as GeoJSON (RFC 7946) and KML 2.2, for GIS tools and mapping apps.

Every alert is exported, candidates and dismissed ones included, each saying which it is (the
``tier`` and ``decision`` properties; in KML also the placemark's name and description).

A KML description is shown as HTML (Google Earth renders it in the placemark's balloon), so
its text is HTML-escaped: operator names, notes and reasons in it stay inert text.

Coordinates keep full float precision. Alerts without a position are never drawn as points:
in GeoJSON they are Features with ``"geometry": null`` (RFC 7946 section 3.2, "unlocated"),
in KML they are listed in the document's description.
"""

from __future__ import annotations

import html
import json
import xml.etree.ElementTree as ET
from collections.abc import Iterable
from typing import Any

from sarmission.alerts.model import Alert, plain_decimal, utc_iso

KML_NS = "http://www.opengis.net/kml/2.2"


def _properties(alert: Alert) -> dict[str, Any]:
    doc = alert.to_json_dict(thumbnail="url")
    del doc["position"]
    return doc


def alerts_geojson(alerts: Iterable[Alert]) -> dict[str, Any]:
    """A GeoJSON FeatureCollection: one Point feature per alert, ``[lon, lat]`` order; alerts
    without a position have a null geometry and their ``position_note`` in the properties."""
    features = []
    for alert in alerts:
        geometry = None
        if alert.position is not None:
            lat, lon = alert.position
            geometry = {"type": "Point", "coordinates": [lon, lat]}
        features.append(
            {
                "type": "Feature",
                "id": alert.alert_id,
                "geometry": geometry,
                "properties": _properties(alert),
            }
        )
    return {"type": "FeatureCollection", "features": features}


def alerts_geojson_bytes(alerts: Iterable[Alert]) -> bytes:
    """:func:`alerts_geojson` serialised as UTF-8 JSON."""
    return json.dumps(alerts_geojson(alerts), ensure_ascii=False).encode()


def _describe(alert: Alert) -> str:
    lines = [
        f"{alert.class_name} score {alert.format_score()}, target {alert.target_id}",
        f"locked {utc_iso(alert.lock_time)} (frame {alert.frame_index})",
    ]
    if alert.position is not None:
        lat, lon = alert.position
        err = f", error {alert.format_error()}" if alert.format_error() else ""
        lines.append(f"position {plain_decimal(lat)}, {plain_decimal(lon)}{err}")
        if alert.position_time is not None:
            lines.append(f"position as of {utc_iso(alert.position_time)}")
        if alert.drift_ne is not None:
            lines.append(alert.format_drift())
    else:
        lines.append(f"position unknown: {alert.position_note or 'no geolocation'}")
    if alert.tier == "candidate":
        lines.append(
            "unconfirmed candidate" + (f", discarded: {alert.discarded}" if alert.discarded else "")
        )
    elif alert.evidence:
        lines.append(f"confirmed: {alert.evidence}")
    if alert.decision is not None:
        lines.append(
            f"{alert.decision} by {alert.decided_by} at {utc_iso(alert.decided_at or 0.0)}"
        )
    if alert.acknowledged:
        lines.append(f"acknowledged by {alert.ack_by} at {utc_iso(alert.ack_time or 0.0)}")
    lines.append(f"alert {alert.alert_id}")
    return "\n".join(lines)


def alerts_kml(alerts: Iterable[Alert], name: str = "sarmission alerts") -> bytes:
    """A KML document (UTF-8 bytes): one Placemark per alert with a position, clamped to the
    ground, with time stamp, description and ExtendedData; the others listed in the
    document's description."""
    ET.register_namespace("", KML_NS)

    def sub(parent: ET.Element, tag: str, text: str | None = None) -> ET.Element:
        el = ET.SubElement(parent, f"{{{KML_NS}}}{tag}")
        if text is not None:
            el.text = text
        return el

    root = ET.Element(f"{{{KML_NS}}}kml")
    document = sub(root, "Document")
    sub(document, "name", name)
    alerts = list(alerts)
    unlocated = [_describe(a).replace("\n", "; ") for a in alerts if a.position is None]
    if unlocated:  # KML wants the description before the placemarks
        text = "Alerts without a position:\n" + "\n".join(unlocated)
        sub(document, "description", html.escape(text))
    for alert in alerts:
        if alert.position is None:
            continue
        lat, lon = alert.position
        placemark = sub(document, "Placemark")
        placemark.set("id", f"alert-{alert.alert_id}")
        state = {"candidate": " (unconfirmed)"}.get(alert.tier, "")
        if alert.dismissed:
            state = " (dismissed)"
        sub(placemark, "name", f"T{alert.target_id} {alert.class_name} {alert.score:.2f}{state}")
        sub(placemark, "description", html.escape(_describe(alert)))
        sub(sub(placemark, "TimeStamp"), "when", utc_iso(alert.lock_time))
        extended = sub(placemark, "ExtendedData")
        for key, value in _properties(alert).items():
            if isinstance(value, (str, int, float, bool)):
                data = sub(extended, "Data")
                data.set("name", key)
                sub(data, "value", str(value))
        point = sub(placemark, "Point")
        sub(point, "altitudeMode", "clampToGround")
        sub(point, "coordinates", f"{plain_decimal(lon)},{plain_decimal(lat)},0")
    return ET.tostring(root, encoding="utf-8", xml_declaration=True)
