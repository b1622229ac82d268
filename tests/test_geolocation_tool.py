"""tools/geolocation_accuracy.py: the live pipeline (simulated vehicle over UDP, MAVLink
telemetry, tracker, lock, geolocation, alert store) with an oracle detector. With exact
telemetry and the camera held at nadir (no ROI action slewing the gimbal), fixes are sub-metre.

The simulator's truth comes from ``sim.truth_frames`` (SciPy, pymap3d), not ``sarmission.geo``.
Its gimbal reports yaw from north here: the legs run east-west, so the heading reaches the
geolocation through the gimbal's quaternion and ``sarmission.geo``'s yaw rotation once. (Yaw
relative to the heading plus ``delta_yaw`` would pass through ``rot_z`` twice, converted in and
out of Euler angles, and a sign error there would cancel.)"""

from conftest import load_tool


def test_exact_telemetry_gives_sub_metre_fixes(tmp_path):
    tool = load_tool("geolocation_accuracy")
    result = tool.measure(
        duration_s=15.0,
        telemetry="exact",
        policy=("alert",),
        workdir=tmp_path,
        gimbal_report="earth",
    )
    assert result["swimmers_in_view"] >= 1
    assert result["alerted"] >= 1, result["console"]
    assert result["false_alerts"] == 0
    assert result["error_m"]["median"] < 1.0, result["per_alert"]
    latency = result["latency_s"]
    # how soon an alert is stored is a benchmark's figure; here only that each one was
    assert latency["stored_s"]["n"] == result["alerts"] and latency["stored_s"]["median"] >= 0
    assert latency["statustext_at_vehicle_s"]["n"] == result["alerts"]
    assert 0 < result["cpu"]["controller_total_share"] < 1.0
    table = tool.markdown([result])
    assert "geolocation error median (m)" in table
