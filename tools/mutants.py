"""The catalogue of planted bugs for ``tools/mutation_check.py``.

Each mutant replaces one snippet (which must occur exactly once in its file) and names the few
test files that must catch it. ``breaks`` says what the bug would get wrong in flight: a
"position", a "lock", a "delivery" (what reaches the autopilot or the store) or a "metric".
When the code moves on and a snippet is gone, the check reports the mutant stale: update it here.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Mutant:
    """One planted bug: ``original`` becomes ``replacement`` in ``path``."""

    name: str
    path: str
    original: str
    replacement: str
    tests: tuple[str, ...]
    breaks: str
    what: str


_TELEMETRY = "sarmission/mavlink/telemetry.py"
_T_INTERP = ("tests/test_telemetry_interpolation.py", "tests/test_telemetry_buffer.py")

_COMMANDS = "sarmission/mavlink/commands.py"
_T_COMMANDS = ("tests/test_command_edges.py",)

_STORE = "sarmission/alerts/store.py"
_MATCHING = "sarmission/evaluation/matching.py"
_SAR = "sarmission/evaluation/sar_metrics.py"
_T_METRICS = ("tests/test_metric_boundaries.py", "tests/test_matching.py",
              "tests/test_sar_metrics.py")

_CONTROLLER = "sarmission/mission/controller.py"
_ACTIONS = "sarmission/mission/actions.py"
_CAMERA_HOLD = "sarmission/mission/camera_hold.py"
_T_PAUSE = ("tests/test_pause_resets.py",)

_FRAMES = "sarmission/geo/frames.py"
_GEOLOCATE = "sarmission/geo/geolocate.py"
_CAMERA = "sarmission/geo/camera.py"
_WGS84 = "sarmission/geo/wgs84.py"
_T_GEO = ("tests/test_geo_oracles.py", "tests/test_geolocate.py", "tests/test_frames.py",
          "tests/test_camera.py")

_LOCK = "sarmission/tracking/lock.py"
_VISITS = "sarmission/mission/visits.py"
_T_LOCK = ("tests/test_lock.py", "tests/test_metric_boundaries.py")
_T_OUTBOX = ("tests/test_mavlink_link.py",)
_T_VISITS = ("tests/test_move_gate.py", "tests/test_actions_visits.py")

MUTANTS: list[Mutant] = [
    # -- telemetry: interpolation and the boot clock --------------------------------------------
    Mutant("telemetry.lerp_weights_reversed", _TELEMETRY,
           "return x + s * (y - x)", "return y + s * (x - y)", _T_INTERP, "position",
           "position interpolated with reversed weights"),
    Mutant("telemetry.slerp_weights_reversed", _TELEMETRY,
           "return slerp(self._attitude.values[i0], self._attitude.values[i1], s)",
           "return slerp(self._attitude.values[i0], self._attitude.values[i1], 1 - s)",
           _T_INTERP, "position", "attitude slerp with reversed weights"),
    Mutant("telemetry.gimbal_frame_change_farther", _TELEMETRY,
           "q, frame = (q0, f0) if s < 0.5 else (q1, f1)",
           "q, frame = (q0, f0) if s > 0.5 else (q1, f1)", _T_INTERP, "position",
           "across a gimbal frame change the farther sample is used"),
    Mutant("telemetry.bracket_fraction_from_end", _TELEMETRY,
           "return i - 1, i, (t - t0) / (t1 - t0)", "return i - 1, i, (t1 - t) / (t1 - t0)",
           _T_INTERP, "position", "interpolation fraction measured from the later sample"),
    Mutant("telemetry.boot_clock_window_never_trims", _TELEMETRY,
           "while self._mins[0][0] < arrival - self.window_s:",
           "while self._mins[0][0] < arrival - 1e9 * self.window_s:", _T_INTERP, "position",
           "the boot clock's minimum delay never leaves the window"),
    Mutant("telemetry.boot_clock_newest_not_least", _TELEMETRY,
           "while self._mins and self._mins[-1][1] >= delay:",
           "while self._mins:", _T_INTERP, "position",
           "the boot clock takes the newest delay, not the least"),
    # -- mavlink: commands -----------------------------------------------------------------------
    Mutant("commands.in_progress_is_final", _COMMANDS,
           "if ack.result == M.MAV_RESULT_IN_PROGRESS:", "if ack.result == -1:",
           _T_COMMANDS, "delivery", "MAV_RESULT_IN_PROGRESS taken as the final answer"),
    Mutant("commands.in_progress_no_extension", _COMMANDS,
           "deadline = time.monotonic() + self.ack_timeout_s\n                continue",
           "continue", _T_COMMANDS, "delivery",
           "MAV_RESULT_IN_PROGRESS does not extend the wait"),
    Mutant("commands.statustext_no_end_marker", _COMMANDS,
           "if len(chunks[-1]) == STATUSTEXT_LEN and len(chunks) < 256:",
           "if len(chunks[-1]) == STATUSTEXT_LEN and len(chunks) < 0:", _T_COMMANDS, "delivery",
           "no empty end chunk after a text of a multiple of 50 characters"),
    Mutant("commands.statustext_single_up_to_49", _COMMANDS,
           "if len(data) <= STATUSTEXT_LEN:", "if len(data) < STATUSTEXT_LEN:", _T_COMMANDS,
           "delivery", "a 50-character text is chunked"),
    Mutant("commands.statustext_no_truncation", _COMMANDS,
           "if len(data) > limit:", "if len(data) > 2 * limit:", _T_COMMANDS, "delivery",
           "texts past 200 characters are not truncated"),
    Mutant("commands.statustext_truncation_mark_lost", _COMMANDS,
           'data = data[: limit - 1] + b"~"', "data = data[:limit]", _T_COMMANDS, "delivery",
           "a truncated text does not end in ~"),
    Mutant("commands.long_confirmation_constant", _COMMANDS,
           "min(attempt, 255),", "0,", ("tests/test_mavlink_link.py",), "delivery",
           "COMMAND_LONG re-sends do not count up their confirmation"),
    # -- evaluation ---------------------------------------------------------------------------
    Mutant("matching.nwd_threshold_inclusive", _MATCHING,
           "valid = sim > nwd_thr", "valid = sim >= nwd_thr", _T_METRICS, "metric",
           "a pair whose NWD equals the threshold matches"),
    Mutant("matching.score_threshold_inclusive", _MATCHING,
           "candidates = np.flatnonzero(detections.scores > score_thr)",
           "candidates = np.flatnonzero(detections.scores >= score_thr)", _T_METRICS, "metric",
           "a detection whose score equals the threshold is a candidate"),
    Mutant("sar.ssr_lockable_denominator", _SAR,
           "search_success_rate=100.0 * len(times) / len(trajectories) if trajectories else None",
           "search_success_rate=(100.0 * len(times) / max(1, sum(t.n_frames >= m for t in "
           "trajectories)) if trajectories else None)", _T_METRICS, "metric",
           "trajectories too short to lock left out of the SSR denominator"),
    # -- alerts: the store --------------------------------------------------------------------
    Mutant("store.deferred_transactions", _STORE,
           'self._conn.execute("BEGIN IMMEDIATE")', 'self._conn.execute("BEGIN")',
           ("tests/test_store_two_writers.py",), "delivery",
           "write transactions begin deferred (two writers: database is locked)"),
    # -- mission: the search pause --------------------------------------------------------------
    Mutant("controller.no_detector_reset_after_pause", _CONTROLLER,
           "            self.detector.reset()\n", "", _T_PAUSE, "lock",
           "the detector keeps its motion state across the pause"),
    Mutant("controller.tracks_kept_after_pause", _CONTROLLER,
           "            self.tracker.drop_tracks()\n", "", _T_PAUSE, "lock",
           "tracks from before the pause go on (a lock without new evidence)"),
    Mutant("camera_hold.refused_release_keeps_pause", _CAMERA_HOLD,
           "(v, Event.RELEASE_REFUSED): View.SURVEY for v in _RELEASES",
           "(v, Event.RELEASE_REFUSED): v for v in _RELEASES", _T_PAUSE, "lock",
           "a refused camera release keeps the search paused"),
    # -- geo ----------------------------------------------------------------------------------
    Mutant("frames.rot_z_sign", _FRAMES,
           "return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])",
           "return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])", _T_GEO, "position",
           "yaw turns the wrong way"),
    Mutant("frames.rot_y_sign", _FRAMES,
           "return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])",
           "return np.array([[c, 0.0, -s], [0.0, 1.0, 0.0], [s, 0.0, c]])", _T_GEO, "position",
           "pitch turns the wrong way"),
    Mutant("frames.rot_x_sign", _FRAMES,
           "return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])",
           "return np.array([[1.0, 0.0, 0.0], [0.0, c, s], [0.0, -s, c]])", _T_GEO, "position",
           "roll turns the wrong way"),
    Mutant("frames.euler_order_xyz", _FRAMES,
           "return rot_z(yaw) @ rot_y(pitch) @ rot_x(roll)",
           "return rot_x(roll) @ rot_y(pitch) @ rot_z(yaw)", _T_GEO, "position",
           "Euler angles composed in the wrong order"),
    Mutant("frames.vehicle_frame_uses_full_attitude", _FRAMES,
           "        return rot_z(vehicle_rpy[2]) @ r_g",
           "        return euler_to_matrix(*vehicle_rpy) @ r_g", _T_GEO, "position",
           "a vehicle-frame gimbal also takes the vehicle's roll and pitch"),
    Mutant("frames.camera_axes_swapped", _FRAMES,
           "        [1.0, 0.0, 0.0],\n        [0.0, 1.0, 0.0],\n    ]\n)",
           "        [0.0, 1.0, 0.0],\n        [1.0, 0.0, 0.0],\n    ]\n)", _T_GEO, "position",
           "image right and image down swapped"),
    Mutant("camera.rays_cx_cy_swapped", _CAMERA,
           "(uv[:, 0] - intr.cx) / intr.fx, (uv[:, 1] - intr.cy) / intr.fy",
           "(uv[:, 0] - intr.cy) / intr.fx, (uv[:, 1] - intr.cx) / intr.fy",
           _T_GEO, "position", "principal point coordinates swapped"),
    Mutant("geolocate.slant_range", _GEOLOCATE, "t = height / float(d[2])",
           "t = height * float(d[2])", _T_GEO, "position", "slant range from the wrong ratio"),
    Mutant("geolocate.ground_sigma_ignored", _GEOLOCATE,
           "sigma_h2 = pose.alt_sigma_m**2 + ground_sigma_m**2", "sigma_h2 = pose.alt_sigma_m**2",
           _T_GEO, "position", "the ground plane's uncertainty left out of the error"),
    Mutant("wgs84.north_east_swapped", _WGS84,
           "        np.asarray(n, dtype=float),\n        np.asarray(e, dtype=float),",
           "        np.asarray(e, dtype=float),\n        np.asarray(n, dtype=float),", _T_GEO,
           "position", "north and east swapped going to WGS84"),
    # -- tracking: the m-of-k lock ------------------------------------------------------------
    Mutant("lock.window_one_too_long", _LOCK, "        if i >= k:\n",
           "        if i >= k + 1:\n", _T_LOCK, "lock", "hits counted over k + 1 frames"),
    Mutant("lock.m_minus_one", _LOCK, "        if count >= m:\n", "        if count >= m - 1:\n",
           _T_LOCK, "lock", "a lock on m - 1 hits"),
    Mutant("lock.online_m_strict", _LOCK,
           "if self.lock_index is None and sum(self._window) >= self.m:",
           "if self.lock_index is None and sum(self._window) > self.m:", _T_LOCK, "lock",
           "the online lock needs m + 1 hits"),
    # -- mavlink: the outbox --------------------------------------------------------------------
    Mutant("outbox.statustext_one_send_short", _COMMANDS,
           "return self.is_text and self.attempts >= self.repeats",
           "return self.is_text and self.attempts >= self.repeats - 1", _T_OUTBOX, "delivery",
           "a STATUSTEXT sent one time fewer than its repeats"),
    # -- mission: where the aircraft may be sent ----------------------------------------------
    Mutant("visits.margin_ignored", _VISITS, "if inside < -self.margin_m:", "if inside < 0:",
           _T_VISITS, "delivery",
           "no margin around the mission area for moving commands"),
    Mutant("visits.error_bound_ignored", _VISITS, "if error_m > self.max_error_m:",
           "if error_m > 10 * self.max_error_m:", _T_VISITS, "delivery",
           "moving commands to fixes with an unbounded error"),
]
