"""Where moving commands may go: inside the mission area or within its margin, with a bounded
error. Probed just inside and just outside the margin (the area: 40-200 m N, +-100 m E)."""

import pymap3d
import pytest

from sarmission.mission.config import load_mission
from sarmission.mission.visits import MoveGate

HOME = (-35.3640, 149.1652)


def at(north: float, east: float) -> tuple[float, float]:
    lat, lon, _ = pymap3d.ned2geodetic(north, east, 0.0, *HOME, 0.0)
    return float(lat), float(lon)


@pytest.fixture
def gate() -> MoveGate:
    mission = load_mission(
        overrides={
            "area.home_lat": HOME[0],
            "area.home_lon": HOME[1],
            "actions.area_margin_m": 200.0,
            "actions.max_error_m": 25.0,
        }
    )
    return MoveGate.from_mission(mission)


@pytest.mark.parametrize(
    ("north", "east", "allowed"),
    [
        (100.0, 0.0, True),  # inside
        (100.0, 150.0, True),  # 50 m outside: within the margin
        (100.0, 295.0, True),  # 195 m outside
        (100.0, 305.0, False),  # 205 m outside
        (-170.0, 0.0, False),  # 210 m south of the area
    ],
)
def test_margin_around_the_area(gate, north, east, allowed):
    refusal = gate.refusal(at(north, east), 3.0)
    assert (refusal == "") is allowed, refusal
    if not allowed:
        assert "outside the mission area (allowed: 200 m)" in refusal


def test_error_bound(gate):
    assert gate.refusal(at(100.0, 0.0), 25.0) == ""
    assert gate.refusal(at(100.0, 0.0), 25.5) == "position error 26 m exceeds 25 m"


@pytest.mark.parametrize(
    ("confidence", "allowed"), [(None, True), (0.29, False), (0.3, True), (0.9, True)]
)
def test_a_target_must_be_likely_enough_when_its_likelihood_is_known(confidence, allowed):
    """With ``min_confidence`` 0.3 an alert 29 % likely a person is not flown to; one without a
    confidence (an operator's confirmation) is; at the default 0 every target is."""
    mission = load_mission(
        overrides={
            "area.home_lat": HOME[0],
            "area.home_lon": HOME[1],
            "actions.min_confidence": 0.3,
        }
    )
    refusal = MoveGate.from_mission(mission).refusal(at(100.0, 0.0), 3.0, confidence)
    assert (refusal == "") is allowed, refusal
    if not allowed:
        assert refusal == "29 % likely a person, below the 30 % that moves the aircraft"
    assert gate_default().refusal(at(100.0, 0.0), 3.0, 0.01) == ""


def gate_default() -> MoveGate:
    home = {"area.home_lat": HOME[0], "area.home_lon": HOME[1]}
    return MoveGate.from_mission(load_mission(overrides=home))


@pytest.mark.parametrize("bad", [-0.1, 1.0, 1.5])
def test_min_confidence_must_be_a_probability_below_one(bad):
    from sarmission.mission.config import MissionConfigError

    with pytest.raises(MissionConfigError, match="min_confidence"):
        load_mission(overrides={"actions.min_confidence": bad})
