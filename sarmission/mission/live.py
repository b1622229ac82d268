"""A live mission: MAVLink link + telemetry + alert store + actions + feed around the controller.

:class:`LiveSession` wires one run together and owns every resource it opens:

1. the alert store (opened first: a bad file fails before anything else starts); the target
   registry is seeded from it and undelivered autopilot actions are queued again;
2. the MAVLink link (our HEARTBEAT as an onboard controller), the wait for the autopilot and the
   stream requests (an ArduPilot autopilot sends nothing else until asked); the telemetry of
   the adopted autopilot only (and its gimbal) goes into the
   :class:`~sarmission.mavlink.telemetry.TelemetryBuffer`, which is emptied when another
   autopilot is adopted (what the old one said is no pose for the new one);
3. the outbox and action policy, the operator feed (optional), the recorder (optional);
4. :meth:`LiveSession.run` reads frames until the source ends, a frame or time limit is reached
   or ``stop`` is set; link loss and recovery are reported on the console as they happen;
5. :meth:`LiveSession.close` gives queued actions a moment to go out, then closes everything
   and returns the summary. What is still queued stays undelivered in the store, for the next run.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Callable, Iterator, Sequence

from sarmission.alerts.cot import CotSender
from sarmission.alerts.cot_relay import CotRelay
from sarmission.alerts.feed import FeedServer
from sarmission.alerts.store import AlertStore
from sarmission.data.frames import Frame
from sarmission.mavlink.commands import CommandSender, Outbox
from sarmission.mavlink.connection import M, MavlinkLink
from sarmission.mavlink.telemetry import (
    MESSAGE_TYPES,
    BootClock,
    TelemetryBuffer,
    height_sigma_m,
)
from sarmission.mission.actions import ActionPolicy
from sarmission.mission.config import MissionConfig
from sarmission.mission.controller import Detector, MissionController
from sarmission.mission.live_sources import LiveSource
from sarmission.mission.session_runner import SessionRunner
from sarmission.mission.visits import MoveGate
from sarmission.viz.recorder import Recorder

log = logging.getLogger(__name__)


def stream_rates(mission: MissionConfig) -> dict[int, float]:
    """Telemetry streams (message id -> Hz) the controller asks the autopilot for."""
    rates = {
        M.MAVLINK_MSG_ID_GLOBAL_POSITION_INT: 10.0,
        M.MAVLINK_MSG_ID_ATTITUDE: 20.0,
        M.MAVLINK_MSG_ID_HOME_POSITION: 0.5,
        M.MAVLINK_MSG_ID_GPS_RAW_INT: 2.0,  # the fix type: no position is believed without one
    }
    if mission.camera.gimbal:
        # as fast as the attitude: a gimbal sample held for 0.2 s while the gimbal slews
        # costs metres on the ground
        rates[M.MAVLINK_MSG_ID_GIMBAL_DEVICE_ATTITUDE_STATUS] = 20.0
    return rates


def telemetry_buffer(mission: MissionConfig, transport_latency_s: float = 0.0) -> TelemetryBuffer:
    """A telemetry buffer for the mission: staleness limit, the camera's fixed mount, and the
    telemetry quality of the ``[telemetry]`` section as the sigmas of each fix's error estimate
    (floored at 0.1 m and 0.1 degree: pixel quantisation and calibration are never exact; the
    height's at 1 m, a barometer's drift, and at 1.5 times the horizontal GNSS error)."""
    gnss_sigma_m = max(mission.telemetry.gnss_noise_m, 0.1)
    return TelemetryBuffer(
        stale_after_s=mission.telemetry.stale_after_s,
        gnss_sigma_m=gnss_sigma_m,
        alt_sigma_m=height_sigma_m(gnss_sigma_m),
        attitude_sigma_rad=math.radians(max(mission.telemetry.attitude_noise_deg, 0.1)),
        mount_rpy=(0.0, math.radians(mission.camera.mount_pitch_deg), 0.0),
        mount_frame="vehicle" if mission.camera.gimbal else "body",
        clock=BootClock(transport_latency_s=transport_latency_s),
        gimbal_pin=(mission.camera.gimbal_component, mission.camera.gimbal_device_id),
    )


class LiveSession:
    """One live run against an autopilot at ``url`` (a pymavlink connection string).

    Args:
        mission: the mission configuration.
        detector: MITE-Net (or anything with its ``process`` interface).
        source: the camera (``read() -> Frame | None``).
        url: the autopilot's MAVLink connection string.
        alerts_db: the alert store file.
        signing_key: MAVLink 2 signing key (32 bytes) or None.
        recorder: rerun recorder or None.
        feed_address: ``(host, port)`` to serve the operator feed on, or None.
        feed_token: the feed's access token (None: none on loopback, else one generated).
        cot_senders: the team's TAK destinations (made, and their TLS files read, before the
            session: a wrong one is an error before anything opens) for the confirmed alerts
            as Cursor-on-Target (:mod:`sarmission.alerts.cot_relay`).
        mission_id: alerts are stored under this id (default: the mission's name).
        transport_latency_s: known minimum telemetry delay (see ``BootClock``).
        connect_timeout_s: how long to wait for the autopilot's HEARTBEAT before going on.
        target_system: the autopilot's system id, pinned (None: the first autopilot heard).
        target_component: the autopilot's component id, pinned (None: any).
        console: receives the operator's console lines.
    """

    def __init__(
        self,
        mission: MissionConfig,
        detector: Detector,
        source: LiveSource,
        url: str,
        alerts_db: str,
        *,
        signing_key: bytes | None = None,
        recorder: Recorder | None = None,
        feed_address: tuple[str, int] | None = None,
        feed_token: str | None = None,
        cot_senders: Sequence[CotSender] = (),
        mission_id: str | None = None,
        transport_latency_s: float = 0.0,
        connect_timeout_s: float = 30.0,
        target_system: int | None = None,
        target_component: int | None = None,
        console: Callable[[str], None] = print,
    ) -> None:
        self.mission = mission
        self.source = source
        self.console = console
        self.recorder = recorder
        self.feed: FeedServer | None = None
        self._feed_token = feed_token
        self.cot: CotRelay | None = None
        self.link: MavlinkLink | None = None
        self.outbox: Outbox | None = None
        self.store = AlertStore(alerts_db)
        try:
            self._open(
                detector,
                url,
                signing_key,
                feed_address,
                mission_id,
                transport_latency_s,
                connect_timeout_s,
                (target_system, target_component),
            )
            if cot_senders:
                self.cot = CotRelay(self.store, cot_senders, self.controller.mission_id).start()
                self.console(
                    "confirmed alerts go to TAK (CoT) at " + ", ".join(s.url for s in cot_senders)
                )
        except BaseException:
            self._close_resources()
            raise
        self.runner = SessionRunner(self.controller)
        self._link_was_ok = True

    @property
    def frames_read(self) -> int:
        """Frames taken from the source so far."""
        return self.runner.frames_read

    def _open(
        self,
        detector: Detector,
        url: str,
        signing_key: bytes | None,
        feed_address: tuple[str, int] | None,
        mission_id: str | None,
        transport_latency_s: float,
        connect_timeout_s: float,
        pin: tuple[int | None, int | None],
    ) -> None:
        mission = self.mission
        self.telemetry = telemetry_buffer(mission, transport_latency_s)
        self.link = MavlinkLink(
            url, signing_key=signing_key, target_system=pin[0], target_component=pin[1]
        )
        self.link.subscribe_autopilot(self.telemetry.handle_message, MESSAGE_TYPES)
        self.link.on_adopted(self._on_adopted)
        self.console(f"waiting for the autopilot on {url} ...")
        if self.link.wait_autopilot(connect_timeout_s):
            system, component = self.link.autopilot or (0, 0)
            self.console(f"autopilot {system}/{component} adopted")
        else:
            why = self.link.diagnosis() or f"no autopilot heard on {url}"
            self.console(
                f"{why} (waited {connect_timeout_s:.0f} s); going on: targets are "
                "alerted without a position until the autopilot's telemetry arrives"
            )
        results = self.link.request_streams(stream_rates(mission))
        refused = [M.enums["MAV_RESULT"][r].name for r in results.values() if r]
        if refused:
            log.info("stream requests answered: %s", ", ".join(refused))
        self.outbox = Outbox(
            CommandSender(self.link, mission.actions.retries, mission.actions.ack_timeout_s)
        )
        ground = mission.area.ground_alt_m
        target_alt = 0.0 if ground is None else ground - mission.area.home_alt_m
        telemetry = self.telemetry
        self.actions = ActionPolicy(
            mission.actions,
            self.outbox,
            self.store,
            survey_altitude_m=mission.flight.altitude_m,
            target_altitude_m=target_alt,
            console=self.console,
            move_gate=MoveGate.from_mission(mission),
            aircraft_position=telemetry.latest_position,
            gimbal_present=lambda: telemetry.gimbal_reported,
            takeover=telemetry.takeover_refusal,
        )
        resumed = self.actions.resume()
        if resumed:
            self.console(f"re-sending {resumed} undelivered autopilot action(s) from the store")
        if feed_address is not None:
            self.feed = FeedServer(self.store, *feed_address, token=self._feed_token).start()
            self.console(self.feed.announcement())
        self.controller = MissionController(
            mission,
            detector,
            self.telemetry,
            self.store,
            actions=self.actions,
            recorder=self.recorder,
            mission_id=mission_id,
            console=self.console,
        )
        if self.controller.known_at_start:
            self.console(
                f"{self.controller.known_at_start} target(s) already alerted in "
                f"mission '{self.controller.mission_id}'; they will not be re-announced"
            )

    def _on_adopted(self, new: tuple[int, int], old: tuple[int, int] | None) -> None:
        """Another autopilot took over (the old one fell silent): nothing the old one said
        may place a target for the new one."""
        if old is None:
            return
        self.telemetry.reset(f"autopilot {old[0]}/{old[1]} replaced by {new[0]}/{new[1]}")
        self.console(
            f"autopilot {old[0]}/{old[1]} silent; now following {new[0]}/{new[1]} "
            "(telemetry buffer emptied)"
        )

    def run(
        self,
        stop: threading.Event | None = None,
        max_frames: int | None = None,
        duration_s: float | None = None,
    ) -> None:
        """Process frames until the source ends, ``max_frames`` were read, ``duration_s``
        passed or ``stop`` is set."""
        watch = getattr(self.source, "watch", None)  # a file's pacing waits end at a stop too
        if watch is not None:
            watch(stop, None if duration_s is None else time.monotonic() + duration_s)
        if self.runner.run(self._frames(), stop, max_frames, duration_s):
            self.console("frame source ended")

    def _frames(self) -> Iterator[Frame]:
        """The source's frames, the link's state reported as each one arrives."""
        while (frame := self.source.read()) is not None:
            self._watch_link()
            yield frame

    def _watch_link(self) -> None:
        assert self.link is not None
        ok = self.link.link_ok
        if ok == self._link_was_ok:
            return
        self._link_was_ok = ok
        if ok:
            self.console(f"link back; {self.actions.pending()} queued action(s) going out")
        else:
            why = self.link.diagnosis() or (f"autopilot silent for {self.link.silence_s():.1f} s")
            self.console(f"link lost: {why}; alerts are kept and queued")

    def close(self, drain_s: float | None = None) -> str:
        """Let queued actions go out for up to ``drain_s`` seconds (while the link is up; by
        default long enough for a STATUSTEXT's repeats), close everything and return the run's
        summary."""
        if drain_s is None:
            a = self.mission.actions
            drain_s = max(3.0, (a.statustext_repeats - 1) * a.statustext_repeat_interval_s + 1.0)
        deadline = time.monotonic() + drain_s
        while (
            self.link is not None
            and self.link.link_ok
            and self.actions.pending()
            and time.monotonic() < deadline
        ):
            time.sleep(0.05)
        lines = [self.controller.summary()]
        assert self.link is not None
        lines.append(
            f"MAVLink: {self.link.received} messages received, "
            f"{self.link.bad_packets} malformed skipped"
            + (
                f", {self.link.rejected_signatures} bad signatures"
                if self.link.rejected_signatures
                else ""
            )
        )
        lines.extend(self._trust_lines())
        if self.cot is not None:
            self.cot.stop()  # what the run confirmed until now has gone out
            lines.append(self.cot.summary())
        if self.source.skipped:
            lines.append(f"frame source: {self.source.skipped} frame(s) could not be read")
        pending = self.actions.pending()
        if pending:
            lines.append(
                f"{pending} autopilot action(s) not finished; they stay queued in "
                f"{self.store.path} for the next run"
            )
        self._close_resources()
        return "\n".join(lines)

    def _trust_lines(self) -> list[str]:
        """What was not believed: telemetry rejected by reason, other senders ignored,
        autopilots adopted, streams given up."""
        assert self.link is not None
        lines = []
        rejected = dict(self.telemetry.rejected)
        if rejected:
            lines.append(
                f"telemetry rejected: {sum(rejected.values())} ("
                + "; ".join(
                    f"{why}: {n}" for why, n in sorted(rejected.items(), key=lambda kv: -kv[1])[:5]
                )
                + ")"
            )
        ignored = dict(self.link.ignored)
        if ignored:
            by_source: dict[tuple[int, int], int] = {}
            for (system, component, _), n in ignored.items():
                by_source[(system, component)] = by_source.get((system, component), 0) + n
            lines.append(
                "ignored (not the adopted autopilot): "
                + ", ".join(f"{n} from {s}/{c}" for (s, c), n in sorted(by_source.items()))
            )
        if self.link.adoptions > 1:
            lines.append(f"autopilots adopted: {self.link.adoptions} (re-adopted after silence)")
        given_up = self.link.streams_given_up
        if given_up:
            lines.append(
                "streams accepted but never sent: "
                + ", ".join(
                    M.mavlink_map[i].msgname if i in M.mavlink_map else str(i) for i in given_up
                )
            )
        return lines

    def _close_resources(self) -> None:
        if self.cot is not None:
            self.cot.stop()
        if self.outbox is not None:
            self.outbox.close()
        if self.feed is not None:
            self.feed.stop()
        if self.recorder is not None:
            self.recorder.close()
        if self.link is not None:
            self.link.close()
        self.source.close()
        self.store.close()
