"""Alerts through a lossy link over real UDP on 127.0.0.1: the action policy, outbox, store and
MAVLink link are the real ones; a seeded relay (``lossy_udp``) loses 30 % of the datagrams both
ways, duplicates, delays and reorders them; the simulated vehicle counts what reaches it.

STATUSTEXT has no acknowledgement: the alert is sent ``statustext_repeats`` times (default 5;
1 - 0.3^5 = 99.8 % reach the vehicle at 30 % independent loss), each time with the alert's short
id first so the copies are recognisable, and the store says how often it was sent, never that
it was delivered.
"""

from collections import Counter

from alert_samples import make_alert
from conftest import free_udp_port, wait_until
from lossy_udp import DOWN, UP, LossyUdpProxy

from sarmission.alerts.model import CHANNEL_MAVLINK
from sarmission.alerts.store import AlertStore
from sarmission.mavlink.commands import CommandSender, Outbox
from sarmission.mavlink.connection import MavlinkLink
from sarmission.mission.actions import ActionPolicy
from sarmission.mission.config import load_mission
from sim.vehicle import SimVehicle

N_ALERTS = 60
SEED = 7


def settled(proxy: LossyUdpProxy, vehicle: SimVehicle):
    """A condition: nothing held in the relay and nothing new at the vehicle since last asked
    (the last datagrams have arrived)."""
    last: list[tuple[int, int]] = []

    def check() -> bool:
        now = (proxy.stats[UP].forwarded, len(vehicle.statustexts))
        done = proxy.idle() and last == [now]
        last[:] = [now]
        return done

    return check


def test_repeated_statustext_reaches_the_vehicle_through_30_percent_loss(tmp_path):
    mission = load_mission(overrides={"flight.takeoff": False})
    repeats = mission.actions.statustext_repeats
    assert repeats == 5  # the default is what is under test
    vehicle_port = free_udp_port()
    vehicle = SimVehicle(f"udpin:127.0.0.1:{vehicle_port}", mission).start()
    proxy = LossyUdpProxy(vehicle_port, seed=SEED).start()
    link = MavlinkLink(f"udpout:127.0.0.1:{proxy.port}")
    outbox = Outbox(CommandSender(link, retries=3, ack_timeout_s=0.5))
    store = AlertStore(tmp_path / "alerts.db")
    lines: list[str] = []
    try:
        assert link.wait_autopilot(10.0), "no HEARTBEAT through the relay"
        actions = ActionPolicy(
            mission.actions, outbox, store, survey_altitude_m=50.0, console=lines.append
        )
        # fixed alert ids: the same texts, hence the same fate in the seeded relay, every run
        alerts = [make_alert(i, alert_id=f"{SEED:08x}{i:024x}") for i in range(1, N_ALERTS + 1)]
        for alert in alerts:
            store.add(alert)
            assert actions.announce(alert) == 1
        assert wait_until(lambda: not actions.pending(), 120.0), actions.pending()
        assert wait_until(settled(proxy, vehicle), 10.0, step=0.3)
        texts = [s.text for s in vehicle.statustexts]
    finally:
        outbox.close()
        link.close()
        proxy.stop()
        vehicle.stop()

    # >= 99 % of the alerts reached the vehicle, recognisable by their short ids
    by_short_id = Counter(text.split(" ", 1)[0] for text in texts)
    short_ids = [a.short_id for a in alerts]
    assert len(set(short_ids)) == N_ALERTS
    reached = [s for s in short_ids if by_short_id[s]]
    assert len(reached) >= 0.99 * N_ALERTS, f"{len(reached)} of {N_ALERTS} reached the vehicle"
    assert set(by_short_id) <= set(short_ids)
    # duplicates made by the relay were dropped by their MAVLink sequence number
    assert vehicle.duplicates_dropped > 0
    assert max(by_short_id.values()) <= repeats, by_short_id.most_common(3)
    for alert in alerts:
        assert all(
            t == alert.statustext().replace("±", "+-")
            for t in texts
            if t.startswith(alert.short_id + " ")
        )
    # the relay did its damage: about 30 % lost each way, copies made, some held late
    up, down = proxy.stats[UP], proxy.stats[DOWN]
    assert 0.2 < up.loss_rate < 0.4 and 0.2 < down.loss_rate < 0.4, (up.loss_rate, down.loss_rate)
    assert up.duplicated > 0 and up.late > 0

    # the store knows each alert was sent `repeats` times, and never calls it delivered
    with AlertStore(tmp_path / "alerts.db") as reopened:
        stored = reopened.list()
        kinds = {e.kind for e in reopened.events()}
        assert reopened.undelivered(CHANNEL_MAVLINK, repeats) == []
    assert len(stored) == N_ALERTS
    for alert in stored:
        assert alert.delivered == {} and alert.refused == {}
        assert alert.sent[CHANNEL_MAVLINK].count == repeats
        doc = alert.to_json_dict()
        assert doc["delivered"] == {} and doc["sent"][CHANNEL_MAVLINK]["count"] == repeats
    assert kinds == {"new", "sent"}
    assert (
        sum(
            f"STATUSTEXT sent {repeats}x (no acknowledgement exists for STATUSTEXT)" in line
            for line in lines
        )
        == N_ALERTS
    )
    assert not any("delivered" in line or "acknowledged" in line for line in lines)
