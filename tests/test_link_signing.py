"""MAVLink 2 signing on the link, over real UDP on 127.0.0.1: forged packets, wrong setups.

pymavlink 2.4.50 stores a stream's timestamp before it checks the signature: a forger who sends
timestamp 2^48-1 from the autopilot's (link id, system, component) with any signature would make
every later genuine packet "old". The link must keep accepting the real autopilot, count what it
refused, and say in one line why it hears no autopilot when signing is set up wrong.
"""

from __future__ import annotations

import re

import pytest
from conftest import free_udp_port, wait_until
from link_peers import RawPeer
from pymavlink.dialects.v20 import ardupilotmega as M

from sarmission.mavlink.connection import (
    MavlinkLink,
    mavlink2_connection,
    signing_key_from_passphrase,
)

KEY = signing_key_from_passphrase("sar-secret")
MAX_TIMESTAMP = 2**48 - 1


def test_forged_burst_with_max_timestamp_does_not_cut_the_signed_link():
    port = free_udp_port()
    with MavlinkLink(f"udpin:127.0.0.1:{port}", signing_key=KEY, link_timeout_s=2.0) as link:
        adopted: list[tuple] = []
        link.on_adopted(lambda new, old: adopted.append(new))
        heard: list[float] = []
        link.subscribe_autopilot(lambda m, t: heard.append(t), ["HEARTBEAT"])
        with RawPeer(port, 1, key=KEY) as autopilot:
            assert link.wait_autopilot(10.0) and link.autopilot == (1, 1)
            forger = mavlink2_connection(f"udpout:127.0.0.1:{port}", 1, 1)
            try:
                forger.setup_signing(
                    signing_key_from_passphrase("guess"),
                    sign_outgoing=True,
                    link_id=autopilot.link_id,  # the real autopilot's stream
                )
                for _ in range(256):
                    forger.mav.signing.timestamp = MAX_TIMESTAMP
                    forger.mav.heartbeat_send(
                        M.MAV_TYPE_QUADROTOR,
                        M.MAV_AUTOPILOT_ARDUPILOTMEGA,
                        0,
                        0,
                        M.MAV_STATE_ACTIVE,
                    )
            finally:
                forger.close()
            assert wait_until(lambda: link.bad_signatures >= 256, 10.0), link.bad_signatures
            after_burst = len(heard)
            # the real autopilot's signed heartbeats are still taken
            assert wait_until(lambda: len(heard) >= after_burst + 10, 10.0), link.signing_stats
            assert link.link_ok and adopted == [(1, 1)]
            assert link.unsigned_rejected == 0 and link.rejected_signatures == link.bad_signatures
            assert link.diagnosis() is None


@pytest.mark.parametrize(
    ("peer_key", "pattern"),
    [
        (
            None,
            r"autopilot 1/1 sends unsigned messages \(([\d,]+) rejected\): "
            r"signing is not enabled on the autopilot",
        ),
        (
            signing_key_from_passphrase("other"),
            r"([\d,]+) messages with a bad signature from autopilot 1/1: "
            r"the autopilot signs with another key",
        ),
    ],
    ids=["unsigned", "other-key"],
)
def test_signing_mismatch_is_diagnosed(peer_key, pattern):
    port = free_udp_port()
    with MavlinkLink(f"udpin:127.0.0.1:{port}", signing_key=KEY) as link:
        with RawPeer(port, 1, key=peer_key):
            assert wait_until(lambda: link.rejected_signatures >= 20, 10.0)
            assert link.autopilot is None
            if peer_key is None:
                assert link.bad_signatures == 0 and link.unsigned_rejected >= 20
            else:
                assert link.unsigned_rejected == 0 and link.bad_signatures >= 20
            diagnosis = link.diagnosis()
            match = re.fullmatch(pattern, diagnosis or "")
            assert match, diagnosis
            assert int(match.group(1).replace(",", "")) >= 20


def test_unsigned_spoofer_cannot_take_a_signed_link():
    port = free_udp_port()
    with MavlinkLink(f"udpin:127.0.0.1:{port}", signing_key=KEY, link_timeout_s=2.0) as link:
        with RawPeer(port, 77) as spoofer:
            assert wait_until(lambda: link.unsigned_rejected >= 5, 10.0)
            with RawPeer(port, 1, key=KEY):
                assert wait_until(lambda: link.autopilot == (1, 1), 10.0)
                assert link.other_autopilots() == []  # the unsigned one is no candidate
            assert wait_until(lambda: not link.link_ok, 10.0)
            beats = spoofer.heartbeats_sent
            assert wait_until(lambda: spoofer.heartbeats_sent >= beats + 10, 10.0)
            assert link.autopilot == (1, 1) and link.adoptions == 1
