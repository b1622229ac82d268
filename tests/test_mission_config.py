"""Mission configuration: defaults, file and override precedence, clear errors."""

import argparse
from pathlib import Path

import pytest

from sarmission.commands.detector_options import add_detector_options
from sarmission.commands.mission_options import add_mission_options
from sarmission.errors import SarmissionError
from sarmission.mission.config import MissionConfigError, load_mission, parse_override
from sarmission.perception.vstmd import VSTMD

MISSIONS = Path(__file__).resolve().parents[1] / "missions"


def write(tmp_path, text: str) -> Path:
    p = tmp_path / "m.toml"
    p.write_text(text)
    return p


def test_defaults():
    cfg = load_mission()
    assert cfg.lock.m == 3 and cfg.lock.k == 5
    assert cfg.detector.topn == 25
    assert cfg.actions.policy == ["alert"]
    assert cfg.camera.intrinsics().width == 3840
    assert len(cfg.area.polygon_ne()) == 4


@pytest.mark.parametrize("name", ["maritime_demo", "urban_demo"])
def test_example_missions_load(name):
    cfg = load_mission(MISSIONS / f"{name}.toml")
    assert cfg.name == name
    assert 60.0 <= cfg.flight.altitude_m <= 80.0
    assert (cfg.camera.width, cfg.camera.height) == (3840, 2160)


def test_file_overrides_defaults_and_cli_overrides_file(tmp_path):
    p = write(tmp_path, "[flight]\naltitude_m = 55\n[lock]\nm = 2\nk = 4\n")
    cfg = load_mission(p)
    assert cfg.flight.altitude_m == 55.0 and isinstance(cfg.flight.altitude_m, float)
    assert cfg.flight.speed_m_s == 10.0  # default kept
    assert (cfg.lock.m, cfg.lock.k) == (2, 4)
    cfg = load_mission(p, ["flight.altitude_m=90", 'actions.policy=["alert", "roi"]'])
    assert cfg.flight.altitude_m == 90.0
    assert cfg.actions.policy == ["alert", "roi"]
    cfg = load_mission(p, {"lock.m": 4})
    assert cfg.lock.m == 4


def test_calibrated_camera_and_polygon_latlon(tmp_path):
    p = write(
        tmp_path,
        "[area]\nhome_lat = 54.0\nhome_lon = 8.0\n"
        "polygon_latlon = [[54.001, 8.0], [54.001, 8.002], [54.002, 8.002]]\n"
        "[camera]\nfx = 3000.0\ndistortion = [-0.1, 0.01, 0.0, 0.0]\n",
    )
    cfg = load_mission(p)
    intr = cfg.camera.intrinsics()
    assert intr.fx == 3000.0 and intr.fy == 3000.0 and intr.cx == 1919.5
    assert intr.distortion == (-0.1, 0.01, 0.0, 0.0)
    ne = cfg.area.polygon_ne()
    assert ne[0][0] == pytest.approx(111.4, abs=0.5) and abs(ne[0][1]) < 0.01


@pytest.mark.parametrize(
    "text, expected",
    [
        ("[flight\naltitude_m = 1", "invalid TOML"),
        ("[flight]\naltitude = 70", "unknown key 'altitude' in [flight]"),
        ("[flihgt]\naltitude_m = 70", "unknown section [flihgt]"),
        ('[flight]\naltitude_m = "high"', "[flight] altitude_m: expected number, got string"),
        ("[lock]\nm = 2.5", "[lock] m: expected integer, got number"),
        ("[lock]\nm = true", "[lock] m: expected integer, got boolean"),
        ("[lock]\nm = 6\nk = 5", "expected 1 <= m <= k"),
        ("[lock]\nmin_score = 1.2", "[lock] min_score"),
        ("[detector]\ncolour_share = 1.5", "[detector] colour_share"),
        ("[detector]\nds = 3", "[detector] ds: expected one of 1, 2, 4, 8"),
        ("[telemetry]\nlatency_s = -1", "[telemetry] latency_s: expected a number >= 0"),
        ("[confirm]\nmin_size_m = 3.0", "[confirm] sizes/speed/score"),
        ("[confirm]\nmax_extent_m = 1.0", "[confirm] max_extent_m: expected 0"),
        ("[confirm]\nmax_extent_m = nan", "[confirm] max_extent_m"),
        ("[confirm]\nscore_window_s = 30", "[confirm] score_window_s: expected 0"),
        ("[confirm]\nscore_window_s = -1", "[confirm] score_window_s: expected 0"),
        ("[confirm]\nmin_look_change = 1.0", "[confirm] min_look_change: expected 0"),
        ("[confirm]\nmin_look_change = -0.1", "[confirm] min_look_change: expected 0"),
        ("[confirm]\nmin_look_change = nan", "[confirm] min_look_change"),
        ("[geolocation]\nmax_off_nadir_deg = 95", "[geolocation] max_off_nadir_deg"),
        ("[actions]\nvisit_interval_s = -1", "[actions] visit_interval_s: expected a number >= 0"),
        ("[detector]\ncrop_scales = [1.0, -2.0]", "[detector] crop_scales"),
        ("[detector]\nrefine_threshold = 1.5", "[detector] refine_threshold"),
        ('[detector]\nmodel = "head.tflite"', '[detector] model: expected "default", "maritime"'),
        ("[detector]\nmodel = 3", "[detector] model: expected string, got integer"),
        ('[actions]\npolicy = ["alert", "dance"]', "unknown action 'dance'"),
        ("[actions]\nroi_hold_s = 0", "[actions] roi_hold_s: expected a positive number"),
        ("[actions]\nroi_hold_s = nan", "[actions] roi_hold_s"),
        ("[camera]\nmount_pitch_deg = 30", "mount_pitch_deg"),
        ("[area]\nrectangle_m = [10, 0, 0, 10]", "rectangle_m"),
        ("[area]\nrectangle_m = [0, 0, 10, 10]\npolygon_m = [[0,0],[1,0],[1,1]]", "only one"),
        ("flight = 3", "[flight] must be a table"),
        ('[alerts]\ncot = "udp://tak:6969"', "[alerts] cot: expected array of string"),
        ('[alerts]\ncot = ["udp://tak:6969", "tak:8087"]', "[alerts] cot[1]: CoT destination"),
        ('[alerts]\ncot = ["tcp://tak:8087?ca=ca.pem"]', "only tls:// takes"),
        ("[actions]\nloiter_altitude_m = -20", "[actions] loiter_altitude_m: expected a height"),
        ("[actions]\nloiter_altitude_m = 0", "[actions] loiter_altitude_m"),
        ("[actions]\nloiter_altitude_m = nan", "[actions] loiter_altitude_m"),
        # longitude first (GeoJSON order): 5,000 km away, once a planner that never returned
        (
            "[area]\nhome_lat = 54.17\nhome_lon = 7.89\n"
            "polygon_latlon = [[7.89, 54.17], [7.9, 54.17], [7.9, 54.18]]",
            "within 50 km of home is expected (polygon_latlon: latitude first?)",
        ),
        ("[area]\npolygon_latlon = [[95, 7.9], [54.2, 7.9], [54.2, 8]]", "latitude first"),
        ("[area]\nrectangle_m = [0, 0, 10000, 10000]\nleg_spacing_m = 1", "legs across"),
        ("[area]\nleg_spacing_m = 0.001", "[area] leg_spacing_m: expected at least 1 m"),
        ("[explicit]\nfoo = 1", "unknown section [explicit]"),  # once a TypeError
    ],
)
def test_bad_files_give_clear_errors(tmp_path, text, expected):
    p = write(tmp_path, text)
    with pytest.raises(MissionConfigError) as exc:
        load_mission(p)
    assert expected in str(exc.value)
    assert str(p) in str(exc.value)
    assert isinstance(exc.value, SarmissionError)


def test_missing_file_and_bad_override(tmp_path):
    with pytest.raises(MissionConfigError, match="cannot read"):
        load_mission(tmp_path / "nope.toml")
    with pytest.raises(MissionConfigError, match="expected section.key=value"):
        load_mission(None, ["altitude"])
    with pytest.raises(MissionConfigError, match=r"\[flight\] speed_m_s: expected number"):
        load_mission(None, ["flight.speed_m_s=fast"])
    assert parse_override("detector.ds = 4") == ("detector.ds", 4)


@pytest.mark.parametrize("ds", range(10))
def test_mission_file_model_and_command_line_accept_the_same_ds(ds: int) -> None:
    """One set of pooling factors: what the mission file accepts, vSTMD and --ds accept too."""

    def accepted(check) -> bool:
        try:
            check()
        except (MissionConfigError, ValueError, argparse.ArgumentError):
            return False
        return True

    parser = argparse.ArgumentParser(exit_on_error=False)
    add_detector_options(parser)
    by_file = accepted(lambda: load_mission(None, {"detector.ds": ds}))
    by_model = accepted(lambda: VSTMD(ds=ds))
    by_cli = accepted(lambda: parser.parse_args(["--ds", str(ds)]))
    assert by_file == by_model == by_cli == (ds in (1, 2, 4, 8))


def test_a_command_line_value_is_blamed_on_the_command_line_not_the_file(tmp_path):
    """`--set detector.ds=3` with a valid mission file was reported as the file's error."""
    p = write(tmp_path, "[detector]\nds = 2\n")
    with pytest.raises(MissionConfigError) as exc:
        load_mission(p, ["detector.ds=3"])
    assert str(exc.value).startswith("command line (an option or --set): [detector] ds")
    bad = write(tmp_path, "[detector]\nds = 3\n")
    with pytest.raises(MissionConfigError, match=str(bad)):
        load_mission(bad, ["flight.altitude_m=80"])  # the file's own error stays the file's
    assert load_mission(bad, ["detector.ds=4"]).detector.ds == 4  # a value the command fixes


def test_a_byte_order_mark_is_read_and_other_encodings_are_named(tmp_path):
    p = tmp_path / "bom.toml"
    p.write_bytes("\ufeff[flight]\naltitude_m = 80\n".encode())
    assert load_mission(p).flight.altitude_m == 80
    p = tmp_path / "latin1.toml"
    p.write_bytes('name = "Küste"\n'.encode("latin-1"))
    with pytest.raises(MissionConfigError, match=rf"{p}: not UTF-8 text"):
        load_mission(p)


@pytest.mark.parametrize("name", ["sea\\u0007search", "sea\\nsearch", "sea\\u0085search"])
def test_a_mission_name_or_id_with_control_characters_is_refused(tmp_path, name):
    """The name is the alerts' mission id, written into CoT and KML (XML, where a control
    character makes the document invalid): refused with one line when the mission loads,
    from the file, a --set override or --mission-id; printable names of any script pass."""
    p = write(tmp_path, f'name = "{name}"\n')
    with pytest.raises(MissionConfigError) as exc:
        load_mission(p)
    assert str(exc.value).startswith(f"{p}: name: expected printable characters only")
    assert "\n" not in str(exc.value)
    decoded = name.encode().decode("unicode_escape")
    with pytest.raises(MissionConfigError, match="command line .*name: expected printable"):
        load_mission(None, {"name": decoded})
    parser = argparse.ArgumentParser(exit_on_error=False)
    add_mission_options(parser)
    with pytest.raises(argparse.ArgumentError, match="expected printable characters only"):
        parser.parse_args(["--mission-id", decoded])
    assert parser.parse_args(["--mission-id", "Küste Nord 2"]).mission_id == "Küste Nord 2"
    assert load_mission(write(tmp_path, 'name = "Küste Nord – 2"\n')).name == "Küste Nord – 2"
