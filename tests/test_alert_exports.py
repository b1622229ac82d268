"""GeoJSON, KML and Cursor-on-Target output of alerts, and the STATUSTEXT line."""

from __future__ import annotations

import html
import json
import math
import socket
import xml.etree.ElementTree as ET

import cv2
import numpy as np
import pytest
from alert_samples import make_alert, sample_frame

from sarmission.alerts.cot import COT_TYPE, CotSender, alert_to_cot
from sarmission.alerts.export import KML_NS, alerts_geojson, alerts_geojson_bytes, alerts_kml
from sarmission.alerts.model import STATUSTEXT_MAX_BYTES
from sarmission.alerts.thumbnail import crop_thumbnail
from sarmission.errors import SarmissionError

LAT, LON = -35.3628123456789, 149.1652345678912


def test_geojson_points_are_lon_lat_at_full_precision() -> None:
    located = make_alert(1, position=(LAT, LON))
    lost = make_alert(2, positioned=False)
    doc = json.loads(alerts_geojson_bytes([located, lost]))
    assert doc["type"] == "FeatureCollection"
    point, unlocated = doc["features"]
    assert point["type"] == "Feature" and point["geometry"]["type"] == "Point"
    assert point["geometry"]["coordinates"] == [LON, LAT]  # RFC 7946: longitude first
    assert f"{point['geometry']['coordinates'][0]:.10f}" == f"{LON:.10f}"
    assert point["properties"]["alert_id"] == located.alert_id
    assert point["properties"]["class_name"] == "swimmer"
    # unlocated: listed with its reason, never drawn as a point
    assert unlocated["geometry"] is None
    assert unlocated["properties"]["position_note"].startswith("telemetry stale")
    assert alerts_geojson([]) == {"type": "FeatureCollection", "features": []}


def test_kml_parses_with_placemarks_at_full_precision() -> None:
    located = [make_alert(1, position=(LAT, LON)), make_alert(2, position=(1e-5, -179.5))]
    lost = make_alert(3, positioned=False)
    root = ET.fromstring(alerts_kml([*located, lost]))
    ns = {"k": KML_NS}
    placemarks = root.findall("k:Document/k:Placemark", ns)
    assert len(placemarks) == 2
    coords = [p.find("k:Point/k:coordinates", ns).text for p in placemarks]
    lon, lat, _ = (float(v) for v in coords[0].split(","))
    assert (lat, lon) == (LAT, LON)
    assert "e" not in coords[1]  # plain decimals, no 1e-05
    assert coords[1].split(",")[:2] == ["-179.5", "0.00001"]
    assert placemarks[0].find("k:TimeStamp/k:when", ns).text.endswith("Z")
    description = root.find("k:Document/k:description", ns).text
    assert lost.alert_id in description and "telemetry stale" in description


def test_kml_and_geojson_say_how_old_a_position_is_and_where_it_drifts() -> None:
    alert = make_alert(1, position_time=1_700_000_005.0, drift_ne=(0.0, -0.4))
    ns = {"k": KML_NS}
    text = ET.fromstring(alerts_kml([alert])).find("k:Document/k:Placemark/k:description", ns)
    assert "position as of 2023-11-14T22:13:25" in text.text
    assert "drifting 0.4 m/s to 270°" in text.text
    (feature,) = alerts_geojson([alert])["features"]
    assert feature["properties"]["drift"]["course_deg"] == 270.0
    assert feature["properties"]["position_time"] == 1_700_000_005.0
    plain = ET.fromstring(alerts_kml([make_alert(2)])).find(
        "k:Document/k:Placemark/k:description", ns
    )
    assert "drifting" not in plain.text and "as of" not in plain.text
    assert "likely" not in plain.text


def test_kml_and_cot_say_how_likely_a_person_is() -> None:
    alert = make_alert(1, score=0.86, confidence=0.07)
    ns = {"k": KML_NS}
    text = ET.fromstring(alerts_kml([alert])).find("k:Document/k:Placemark/k:description", ns)
    assert "swimmer score 0.86 (7 % likely a person)" in text.text
    (feature,) = alerts_geojson([alert])["features"]
    assert feature["properties"]["confidence"] == 0.07
    remarks = ET.fromstring(alert_to_cot(alert, now=1.0)).find("detail/remarks").text
    assert remarks.startswith("swimmer score 0.86 (7 % likely a person), target 1")


def test_cot_event_has_full_precision_point_and_required_attributes() -> None:
    alert = make_alert(5, position=(LAT, LON), error_m=3.7, lock_time=1_700_000_000.25)
    event = ET.fromstring(alert_to_cot(alert, now=1_700_000_010.0, stale_after_s=600))
    assert event.tag == "event" and event.get("version") == "2.0"
    assert event.get("type") == COT_TYPE
    assert event.get("uid") == alert.cot_uid
    assert event.get("how")
    assert event.get("time") == "2023-11-14T22:13:30.000Z"
    assert event.get("start") == "2023-11-14T22:13:20.250Z"
    assert event.get("stale") == "2023-11-14T22:23:30.000Z"
    point = event.find("point")
    assert point is not None
    assert float(point.get("lat")) == LAT and float(point.get("lon")) == LON
    assert len(point.get("lat").split(".")[1]) >= 10  # not a 4-decimal rounding
    assert float(point.get("ce")) == 3.7
    assert float(point.get("hae")) == 9999999.0 and float(point.get("le")) == 9999999.0
    assert alert.alert_id in event.find("detail/remarks").text


def test_cot_uid_is_stable_per_target() -> None:
    a, b = make_alert(4), make_alert(4, score=0.5)
    assert a.alert_id != b.alert_id
    uid = ET.fromstring(alert_to_cot(a)).get("uid")
    assert uid == ET.fromstring(alert_to_cot(b)).get("uid")
    assert uid != ET.fromstring(alert_to_cot(make_alert(5))).get("uid")


def test_cot_refuses_alert_without_position() -> None:
    with pytest.raises(ValueError, match="no position"):
        alert_to_cot(make_alert(1, positioned=False))


def test_cot_goes_out_only_for_confirmed_alerts_not_dismissed() -> None:
    with pytest.raises(ValueError, match="unconfirmed candidate"):
        alert_to_cot(make_alert(1, tier="candidate"))
    with pytest.raises(ValueError, match="dismissed"):
        alert_to_cot(make_alert(1, decision="dismissed", decided_by="ana", decided_at=5.0))
    promoted = make_alert(
        1,
        tier="confirmed",
        evidence="held 4 s",
        decision="confirmed",
        decided_by="ana",
        decided_at=5.0,
    )
    assert ET.fromstring(alert_to_cot(promoted)).get("uid") == promoted.cot_uid


def test_exports_say_which_alerts_are_candidates_or_dismissed() -> None:
    cand = make_alert(1, tier="candidate", discarded="drifts 3 m/s", evidence="drifts 3 m/s")
    gone = make_alert(2, decision="dismissed", decided_by="ana", decided_at=1_700_000_000.0)
    sure = make_alert(3, evidence="held 4.2 s within 3 m")
    ns = {"k": KML_NS}
    placemarks = ET.fromstring(alerts_kml([cand, gone, sure])).findall("k:Document/k:Placemark", ns)
    names = [p.find("k:name", ns).text for p in placemarks]
    assert names == [
        "T1 swimmer 0.91 (unconfirmed)",
        "T2 swimmer 0.91 (dismissed)",
        "T3 swimmer 0.91",
    ]
    descriptions = [p.find("k:description", ns).text for p in placemarks]
    assert "unconfirmed candidate, discarded: drifts 3 m/s" in descriptions[0]
    assert "dismissed by ana at 2023-11-14T22:13:20.000Z" in descriptions[1]
    assert "confirmed: held 4.2 s within 3 m" in descriptions[2]
    props = [f["properties"] for f in alerts_geojson([cand, gone, sure])["features"]]
    assert [(p["tier"], p["decision"]) for p in props] == [
        ("candidate", None),
        ("confirmed", "dismissed"),
        ("confirmed", None),
    ]


def test_cot_over_udp_arrives() -> None:
    receiver = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
    receiver.bind(("127.0.0.1", 0))
    receiver.settimeout(3.0)
    alert = make_alert(2, position=(LAT, LON))
    with receiver, CotSender(f"udp://127.0.0.1:{receiver.getsockname()[1]}") as sender:
        sender.send_alert(alert)
        data, _ = receiver.recvfrom(65536)
    event = ET.fromstring(data)
    assert event.get("uid") == alert.cot_uid
    assert float(event.find("point").get("lat")) == LAT


def test_cot_over_tcp_arrives() -> None:
    server = socket.create_server(("127.0.0.1", 0))
    server.settimeout(3.0)
    alert = make_alert(2, position=(LAT, LON))
    with server, CotSender(f"tcp://127.0.0.1:{server.getsockname()[1]}") as sender:
        sender.send_alert(alert)
        conn, _ = server.accept()
        with conn:
            conn.settimeout(3.0)
            sender.close()
            data = b"".join(iter(lambda: conn.recv(65536), b""))
    assert ET.fromstring(data).get("uid") == alert.cot_uid


@pytest.mark.parametrize("url", ["http://x:1", "udp://host", "tak.example:8087"])
def test_cot_sender_rejects_bad_urls(url: str) -> None:
    with pytest.raises(SarmissionError):
        CotSender(url)


def test_statustext_format_and_limit() -> None:
    alert = make_alert(
        1, position=(-35.362912, 149.165234), score=0.912, error_m=4.4, alert_id="0" * 32
    )
    assert alert.short_id == "T1-qx"  # a hash of the stored alert id: the same after restarts
    assert alert.statustext() == "T1-qx SAR swimmer 0.91 -35.36291,149.16523 ±4m"
    blind = make_alert(1, positioned=False, alert_id="0" * 32)
    assert blind.statustext() == "T1-qx SAR swimmer 0.91 pos unknown"
    worst = make_alert(
        1,
        class_name="person_in_water_with_lifejacket_and_more",
        position=(-89.123456, -179.123456),
        error_m=123456.0,
        score=1.0,
    )
    text = worst.statustext()
    assert len(text.encode()) <= STATUSTEXT_MAX_BYTES
    assert text.startswith(f"{worst.short_id} SAR pers ")
    assert text.endswith("-89.12346,-179.12346 ±123456m")

    # the name goes first; with no room even without it, the error radius: never a cut number
    def extreme(target_id: int) -> str:
        alert = make_alert(
            target_id,
            class_name="person",
            position=(-89.123456, -179.123456),
            error_m=123456.0,
            score=1.0,
        )
        return alert.statustext().removeprefix(alert.short_id)

    assert extreme(123456) == " SAR 1.00 -89.12346,-179.12346 ±123456m"
    assert extreme(1234567) == " SAR person 1.00 -89.12346,-179.12346"


def test_short_ids_tell_alerts_of_one_target_apart() -> None:
    ids = {make_alert(7).short_id for _ in range(40)}  # 40 alerts of target 7, fresh ids
    assert all(i.startswith("T7-") and len(i) == 5 and i.isascii() for i in ids)
    assert len(ids) >= 35  # 961 suffixes: a few collisions at most
    assert make_alert(7).to_json_dict()["short_id"].startswith("T7-")


def test_alert_rejects_impossible_positions() -> None:
    with pytest.raises(ValueError):
        make_alert(1, position=(91.0, 0.0))
    with pytest.raises(ValueError):
        make_alert(1, position=(float("nan"), 0.0))


def test_thumbnail_is_a_jpeg_crop_centred_on_the_target() -> None:
    frame = sample_frame()
    jpeg = crop_thumbnail(frame, (160, 120), side=32, out_size=128)
    image = cv2.imdecode(np.frombuffer(jpeg, np.uint8), cv2.IMREAD_COLOR)
    assert image.shape == (128, 128, 3)
    centre, corner = image[60:68, 60:68].mean(axis=(0, 1)), image[:8, :8].mean(axis=(0, 1))
    assert centre[2] > 150 > corner[2]  # the red-ish swimmer is in the middle
    edge = cv2.imdecode(np.frombuffer(crop_thumbnail(frame, (0, 0), 32, 32), np.uint8), 1)
    assert edge[:12, :12].max() < 20  # outside the frame is black


def test_a_life_ring_alert_reads_as_one_and_is_no_casualty() -> None:
    ring = make_alert(
        2,
        class_name="life_saving_appliances",
        position=(-35.362912, 149.165234),
        score=0.8,
        error_m=3.0,
        alert_id="1" * 32,
    )
    assert ring.statustext() == f"{ring.short_id} SAR life ring 0.80 -35.36291,149.16523 ±3m"
    event = ET.fromstring(alert_to_cot(ring, now=1_700_000_010.0))
    assert event.get("type") == "b-m-p-s-m" != COT_TYPE
    assert event.find("detail/contact").get("callsign") == "SAR T2 life ring"
    swimmer = ET.fromstring(alert_to_cot(make_alert(3, position=(LAT, LON)), now=1.0))
    assert swimmer.get("type") == COT_TYPE


def test_cot_remarks_say_how_old_the_position_is() -> None:
    alert = make_alert(1, position_time=1_700_000_005.0)
    event = ET.fromstring(alert_to_cot(alert, now=1_700_000_010.0))
    assert "position as of 2023-11-14T22:13:25" in event.find("detail/remarks").text


def test_cot_carries_a_drifting_swimmer_s_course_and_speed() -> None:
    """TAK draws a marker's motion from ``track``: a drift to the south-west at 0.5 m/s goes
    out as course 225, speed 0.5; a still target as speed 0; none when not estimated."""
    s = math.sqrt(0.125)
    drifting = ET.fromstring(alert_to_cot(make_alert(1, drift_ne=(-s, -s)), now=1.0))
    track = drifting.find("detail/track")
    assert float(track.get("course")) == pytest.approx(225.0, abs=0.05)
    assert float(track.get("speed")) == pytest.approx(0.5, abs=0.005)
    assert "drifting 0.5 m/s to 225°" in drifting.find("detail/remarks").text
    still = ET.fromstring(alert_to_cot(make_alert(1, drift_ne=(0.0, 0.0)), now=1.0))
    assert float(still.find("detail/track").get("speed")) == 0.0
    assert ET.fromstring(alert_to_cot(make_alert(1), now=1.0)).find("detail/track") is None


def test_kml_descriptions_keep_names_and_notes_as_inert_text() -> None:
    """Google Earth renders a description as HTML: markup in an operator's name, a note or
    a reason is escaped there, so it shows as the text it is."""
    markup = '<img src=x onerror="alert(1)"> & <script>'
    acked = make_alert(
        1,
        decision="dismissed",
        decided_by=markup,
        decided_at=1_700_000_000.0,
        ack_by="<b>bo</b>",
        ack_time=1_700_000_000.0,
        evidence=markup,
    )
    lost = make_alert(2, positioned=False, position_note=markup)
    ns = {"k": KML_NS}
    root = ET.fromstring(alerts_kml([acked, lost]))
    for description in (
        root.find("k:Document/k:Placemark/k:description", ns).text,
        root.find("k:Document/k:description", ns).text,
    ):
        assert "<" not in description and ">" not in description and '"' not in description
        assert html.escape(markup) in description
        assert markup in html.unescape(description)
    placemark = root.find("k:Document/k:Placemark/k:description", ns).text
    assert "acknowledged by &lt;b&gt;bo&lt;/b&gt; at" in placemark
