"""Stream watchdog over real UDP on 127.0.0.1: a stream accepted but never sent is given up.

The peer acknowledges every MAV_CMD_SET_MESSAGE_INTERVAL with ACCEPTED, as ArduPilot does, but
sends only the streams it can (here ATTITUDE, never GIMBAL_DEVICE_ATTITUDE_STATUS: no mount).
"""

from __future__ import annotations

import logging

from conftest import free_udp_port, wait_until
from link_peers import RawPeer
from pymavlink.dialects.v20 import ardupilotmega as M

from sarmission.mavlink.connection import MavlinkLink

GIMBAL = M.MAVLINK_MSG_ID_GIMBAL_DEVICE_ATTITUDE_STATUS
ATTITUDE = M.MAVLINK_MSG_ID_ATTITUDE
TRIES = 3


def test_stream_accepted_but_never_sent_is_given_up(caplog):
    caplog.set_level(logging.INFO, logger="sarmission.mavlink")
    port = free_udp_port()
    attitudes: list[float] = []
    link = MavlinkLink(
        f"udpin:127.0.0.1:{port}",
        link_timeout_s=2.0,
        stream_retry_s=0.25,  # the backoff runs 0.25, 0.5, 1, 2 ... s: a short test
        stream_max_tries=TRIES,
    )
    peer = RawPeer(port, 1, ack_intervals=True, honour={ATTITUDE})
    try:
        link.subscribe_autopilot(lambda m, t: attitudes.append(t), ["ATTITUDE"])
        assert link.wait_autopilot(10.0)
        assert link.request_streams({GIMBAL: 5.0, ATTITUDE: 10.0}) == {
            GIMBAL: M.MAV_RESULT_ACCEPTED,
            ATTITUDE: M.MAV_RESULT_ACCEPTED,
        }
        assert wait_until(lambda: link.streams_given_up == [GIMBAL], 30.0)
        assert peer.requests_for(GIMBAL) == TRIES
        given_up = [r.message for r in caplog.records if "giving up" in r.message]
        assert given_up == [
            "GIMBAL_DEVICE_ATTITUDE_STATUS: accepted by the autopilot but never sent after "
            "3 requests; giving up"
        ]
        assert peer.requests_for(ATTITUDE) == 1 and attitudes

        # the autopilot reboots and forgets its streams: ATTITUDE, which came before, is asked
        # for again and again (beyond the tries a never-seen stream gets), the gimbal never
        peer.honour.clear()
        peer.forget_streams()
        assert wait_until(lambda: peer.requests_for(ATTITUDE) >= 2 + TRIES, 30.0)
        assert link.streams_given_up == [GIMBAL] and peer.requests_for(GIMBAL) == TRIES
        peer.honour.add(ATTITUDE)
        n = len(attitudes)
        assert wait_until(lambda: len(attitudes) > n + 5, 30.0)
        assert peer.requests_for(GIMBAL) == TRIES
        assert sum("giving up" in r.message for r in caplog.records) == 1

        # the gimbal turns up after all (an accepted interval stays in force): taken back
        peer.honour.add(GIMBAL)
        peer.start_stream(GIMBAL, 0.2)
        assert wait_until(lambda: link.streams_given_up == [], 10.0)
        assert "GIMBAL_DEVICE_ATTITUDE_STATUS: arrives after all" in caplog.text
    finally:
        peer.close()
        link.close()
