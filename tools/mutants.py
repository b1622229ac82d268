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

_TELEMETRY_CHECKS = "sarmission/mavlink/telemetry_checks.py"
_T_TRUST = ("tests/test_telemetry_trust.py", "tests/test_telemetry_checks.py")
_ADOPTION = "sarmission/mavlink/adoption.py"
_T_ADOPTION = ("tests/test_adoption_rules.py",)
_CONFIRMATION = "sarmission/mission/confirmation.py"
_CANDIDATES = "sarmission/mission/candidates.py"
_ALERT_MODEL = "sarmission/alerts/model.py"
_T_CONFIRM = ("tests/test_confirmation.py", "tests/test_confirmation_boundaries.py")
_T_ZONES = ("tests/test_confirmation_boundaries.py", "tests/test_alert_tiers.py")
_SCORING = "sarmission/evaluation/alert_scoring.py"
_T_SCORING = ("tests/test_alert_scoring.py", "tests/test_alert_scoring_boundaries.py")
_T_GEO_LIVE = ("tests/test_geolocation_tool.py",)
_T_GEO_ERROR = ("tests/test_geo_oracles.py", "tests/test_geolocate.py", "tests/test_geo_grazing.py")
_T_GIMBAL = ("tests/test_telemetry_buffer.py", "tests/test_camera.py", "tests/test_geo_oracles.py")

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

    # -- geo: frames, axes, the error model ----------------------------------------------------
    Mutant("frames.rot_z_sign_live", _FRAMES,
           "return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])",
           "return np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])", _T_GEO_LIVE,
           "position", "yaw turns the wrong way (the live pipeline against the simulator)"),
    Mutant("frames.gimbal_vehicle_frame_as_earth", _FRAMES,
           "        return rot_z(vehicle_rpy[2]) @ r_g", "        return r_g", _T_GIMBAL,
           "position", "a vehicle-frame gimbal's yaw taken from north"),
    Mutant("frames.gimbal_earth_frame_as_body", _FRAMES,
           'if gimbal_frame == "earth":\n        return r_g',
           'if gimbal_frame == "earth":\n        return euler_to_matrix(*vehicle_rpy) @ r_g',
           _T_GIMBAL, "position", "an earth-frame gimbal also turned by the vehicle's attitude"),
    Mutant("frames.yaw_lock_flag_ignored", _FRAMES,
           'return "earth" if flags & GIMBAL_DEVICE_FLAGS_YAW_LOCK else "vehicle"',
           'return "vehicle"', _T_GIMBAL, "position",
           "a gimbal with only YAW_LOCK set read in the vehicle frame"),
    Mutant("frames.earth_flag_ignored", _FRAMES,
           "if flags & GIMBAL_DEVICE_FLAGS_YAW_IN_EARTH_FRAME:",
           "if flags & 0:", _T_GIMBAL, "position",
           "YAW_IN_EARTH_FRAME not read (an earth-frame gimbal taken as vehicle-frame)"),
    Mutant("telemetry.delta_yaw_sign", _TELEMETRY,
           "q = matrix_to_quaternion(rot_z(msg.delta_yaw) @ quaternion_to_matrix(q))",
           "q = matrix_to_quaternion(rot_z(-msg.delta_yaw) @ quaternion_to_matrix(q))",
           _T_GIMBAL, "position", "the gimbal's delta_yaw applied the wrong way"),
    Mutant("wgs84.ned_as_enu", _WGS84, "lat, lon, h = pymap3d.ned2geodetic(",
           "lat, lon, h = pymap3d.enu2geodetic(", _T_GEO, "position",
           "NED offsets taken as ENU going to WGS84"),
    Mutant("wgs84.geodetic_to_enu", _WGS84, "n, e, d = pymap3d.geodetic2ned(",
           "n, e, d = pymap3d.geodetic2enu(", _T_GEO, "position",
           "WGS84 to ENU where NED is meant"),
    Mutant("geolocate.gnss_sigma_ignored", _GEOLOCATE,
           "cov = pose.gnss_sigma_m**2 * np.eye(2)", "cov = 0.0 * np.eye(2)", _T_GEO_ERROR,
           "position", "the GNSS error left out of the error"),
    Mutant("geolocate.alt_sigma_ignored", _GEOLOCATE,
           "sigma_h2 = pose.alt_sigma_m**2 + ground_sigma_m**2", "sigma_h2 = ground_sigma_m**2",
           _T_GEO_ERROR, "position", "the altitude error left out of the error"),
    Mutant("geolocate.attitude_term_ignored", _GEOLOCATE,
           "cov += pose.attitude_sigma_rad**2 * jac @ jac.T", "cov += 0.0 * jac @ jac.T",
           _T_GEO_ERROR, "position", "the pointing error left out of the error"),
    Mutant("geolocate.height_slide_per_metre_of_ray", _GEOLOCATE,
           "dh = d[:2] / dz", "dh = d[:2]", _T_GEO_ERROR, "position",
           "a height error slides the point by the ray's direction, not per metre of height"),
    Mutant("geolocate.error_north_only", _GEOLOCATE,
           "error = math.sqrt(float(np.trace(cov)))", "error = math.sqrt(float(cov[0, 0]))",
           _T_GEO_ERROR, "position", "the error from the north variance only"),
    Mutant("geolocate.horizon_margin_in_radians", _GEOLOCATE,
           "margin = math.degrees(self.horizon_sigmas * attitude_sigma_rad)",
           "margin = self.horizon_sigmas * attitude_sigma_rad", _T_GEO_ERROR, "position",
           "the grazing margin compared in radians against degrees"),
    Mutant("geolocate.off_nadir_is_depression", _GEOLOCATE,
           "off_nadir = 90.0 - fix.depression_deg", "off_nadir = fix.depression_deg",
           _T_GEO_ERROR, "position", "off-nadir angle taken as the depression"),
    # -- mavlink: telemetry plausibility and time windows ----------------------------------------
    Mutant("checks.lat_range_180", _TELEMETRY_CHECKS, "if not -90.0 <= lat_deg <= 90.0:",
           "if not -180.0 <= lat_deg <= 180.0:", _T_TRUST, "position",
           "latitudes up to 180 degrees believed"),
    Mutant("checks.speed_in_mm_s", _TELEMETRY_CHECKS,
           "speed = math.sqrt(msg.vx**2 + msg.vy**2 + msg.vz**2) / 100.0",
           "speed = math.sqrt(msg.vx**2 + msg.vy**2 + msg.vz**2) / 1000.0", _T_TRUST,
           "position", "velocity read in mm/s (implausible speeds believed)"),
    Mutant("checks.rel_alt_in_cm", _TELEMETRY_CHECKS,
           'problem = problem or _in(msg.relative_alt / 1000.0, REL_ALT_RANGE_M, "relative_alt")',
           'problem = problem or _in(msg.relative_alt / 100000.0, REL_ALT_RANGE_M, '
           '"relative_alt")', _T_TRUST, "position", "relative altitude checked in the wrong unit"),
    Mutant("checks.pitch_range_pi", _TELEMETRY_CHECKS,
           "abs(msg.pitch) > math.pi / 2 + 1e-3", "abs(msg.pitch) > math.pi + 1e-3", _T_TRUST,
           "position", "pitch beyond 90 degrees believed"),
    Mutant("checks.quaternion_norm_loose", _TELEMETRY_CHECKS,
           "if abs(norm - 1.0) > QUATERNION_NORM_TOLERANCE:",
           "if abs(norm - 1.0) > 10 * QUATERNION_NORM_TOLERANCE:", _T_TRUST, "position",
           "quaternions far from unit norm believed"),
    Mutant("checks.home_at_zero_believed", _TELEMETRY_CHECKS,
           'if lat == 0 and lon == 0:\n        return "home at 0, 0"',
           'if lat == 0 and lon == 0 and False:\n        return "home at 0, 0"', _T_TRUST,
           "position", "a home at 0, 0 (no home yet) believed"),
    Mutant("telemetry.jump_check_window_long", _TELEMETRY, "if dt > JUMP_CHECK_S:",
           "if dt > 10 * JUMP_CHECK_S:", _T_TRUST, "position",
           "positions far apart in time checked against each other for jumps"),
    Mutant("telemetry.jump_check_window_short", _TELEMETRY, "if dt > JUMP_CHECK_S:",
           "if dt > JUMP_CHECK_S / 10:", _T_TRUST, "position",
           "jumps checked only between positions close in time"),
    Mutant("telemetry.jump_least_interval", _TELEMETRY,
           "if distance > MAX_SPEED_MPS * max(dt, 0.1) + JUMP_SLACK_M:",
           "if distance > MAX_SPEED_MPS * max(dt, 1.0) + JUMP_SLACK_M:", _T_TRUST, "position",
           "a jump between close positions allowed a second's flight"),
    Mutant("telemetry.jump_no_slack", _TELEMETRY,
           "if distance > MAX_SPEED_MPS * max(dt, 0.1) + JUMP_SLACK_M:",
           "if distance > MAX_SPEED_MPS * max(dt, 0.1):", _T_TRUST, "position",
           "no slack for GNSS noise in the jump check"),
    Mutant("telemetry.gps_fix_age_long", _TELEMETRY, "if arrival - gps[0] > GPS_FIX_MAX_AGE_S:",
           "if arrival - gps[0] > 10 * GPS_FIX_MAX_AGE_S:", _T_TRUST, "position",
           "an old GPS_RAW_INT still vouches for the fix"),
    Mutant("telemetry.gps_2d_fix_believed", _TELEMETRY, "if gps[1] < GPS_FIX_3D:",
           "if gps[1] < GPS_FIX_3D - 1:", _T_TRUST, "position",
           "positions believed with a 2D fix"),
    Mutant("telemetry.stale_gap_by_nearer_sample", _TELEMETRY,
           "if min(t - t0, t1 - t) > stale_s:", "if max(t - t0, t1 - t) > stale_s:",
           _T_INTERP, "position", "a gap is stale by the farther sample, not the nearer"),
    Mutant("bootclock.reboot_jump_long", _TELEMETRY,
           "if boot_s < self._last_boot - self.reboot_jump_s:",
           "if boot_s < self._last_boot - 10 * self.reboot_jump_s:", _T_TRUST, "position",
           "a jump back in boot time of seconds kept on the timeline"),
    Mutant("bootclock.late_tolerance_long", _TELEMETRY,
           "return least - self.future_tolerance_s <= delay <= least + self.late_tolerance_s",
           "return least - self.future_tolerance_s <= delay <= least + 10 * "
           "self.late_tolerance_s", _T_TRUST, "position",
           "samples far later than the least delay kept on the timeline"),
    Mutant("bootclock.future_tolerance_long", _TELEMETRY,
           "return least - self.future_tolerance_s <= delay <= least + self.late_tolerance_s",
           "return least - 10 * self.future_tolerance_s <= delay <= least + "
           "self.late_tolerance_s", _T_TRUST, "position",
           "samples from seconds in the future kept on the timeline"),
    Mutant("bootclock.new_timeline_on_two", _TELEMETRY, "return (cand[2] + 1 >= 3 and",
           "return (cand[2] + 1 >= 2 and", _T_TRUST, "position",
           "a new timeline adopted on two samples"),
    # -- mavlink: which sender is the autopilot --------------------------------------------------
    Mutant("adoption.invalid_autopilot_adopted", _ADOPTION,
           "        and msg.autopilot != M.MAV_AUTOPILOT_INVALID\n", "", _T_ADOPTION, "delivery",
           "a HEARTBEAT with MAV_AUTOPILOT_INVALID taken as an autopilot"),
    Mutant("adoption.gimbal_component_adopted", _ADOPTION,
           "        and msg.get_srcComponent() not in GIMBAL_COMPONENTS\n", "", _T_ADOPTION,
           "delivery", "a gimbal component taken as an autopilot"),
    Mutant("adoption.gcs_adopted", _ADOPTION, "        M.MAV_TYPE_GCS,\n", "", _T_ADOPTION,
           "delivery", "a ground station taken as an autopilot"),
    Mutant("adoption.readopt_while_alive", _ADOPTION,
           "if self.adopted is not None and silent <= self.link_timeout_s:",
           "if self.adopted is not None and silent <= 0.0:", _T_ADOPTION, "delivery",
           "another autopilot adopted while the adopted one is alive"),
    Mutant("adoption.readopt_at_timeout", _ADOPTION,
           "if self.adopted is not None and silent <= self.link_timeout_s:",
           "if self.adopted is not None and silent < self.link_timeout_s:", _T_ADOPTION,
           "delivery", "another autopilot adopted at exactly the link timeout"),
    Mutant("adoption.pinned_component_ignored", _ADOPTION,
           "self.target_component is None or src[1] == self.target_component",
           "self.target_component is None or True", _T_ADOPTION, "delivery",
           "the pinned component not enforced"),
    Mutant("adoption.gimbal_of_any_system", _ADOPTION,
           "if src[0] == adopted[0] and src[1] in GIMBAL_COMPONENTS:",
           "if src[1] in GIMBAL_COMPONENTS:", _T_ADOPTION, "position",
           "gimbal attitude believed from another system's gimbal"),
    # -- mission: confirmation and candidates -----------------------------------------------------
    Mutant("confirmation.speed_gate_no_error", _CONFIRMATION,
           "and speed - 2 * spread > rule.max_speed_m_s:", "and speed > rule.max_speed_m_s:",
           _T_CONFIRM, "lock", "the speed gate ignores the fit's standard error"),
    Mutant("confirmation.speed_gate_error_added", _CONFIRMATION,
           "and speed - 2 * spread > rule.max_speed_m_s:",
           "and speed + 2 * spread > rule.max_speed_m_s:", _T_CONFIRM, "lock",
           "the speed gate adds the standard error instead of subtracting it"),
    Mutant("confirmation.size_max_exclusive", _CONFIRMATION,
           "not rule.min_size_m <= size <= rule.max_size_m",
           "not rule.min_size_m <= size < rule.max_size_m", _T_CONFIRM, "lock",
           "a size of exactly max_size_m discarded"),
    Mutant("confirmation.size_min_exclusive", _CONFIRMATION,
           "not rule.min_size_m <= size <= rule.max_size_m",
           "not rule.min_size_m < size <= rule.max_size_m", _T_CONFIRM, "lock",
           "a size of exactly min_size_m discarded"),
    Mutant("confirmation.size_mean_not_median", _CONFIRMATION,
           "size = float(np.median(sizes)) if sizes else None",
           "size = float(np.mean(sizes)) if sizes else None", _T_CONFIRM, "lock",
           "the size is the mean of the sightings (one odd box decides)"),
    Mutant("confirmation.seen_share_inclusive", _CONFIRMATION,
           "if share is not None and share < rule.min_seen_share:",
           "if share is not None and share <= rule.min_seen_share:", _T_CONFIRM, "lock",
           "seen in exactly min_seen_share of the frames discarded"),
    Mutant("confirmation.seen_share_one_frame_more", _CONFIRMATION,
           "return len(self.sightings) / self.frames if self.frames else 0.0",
           "return len(self.sightings) / (self.frames + 1) if self.frames else 0.0", _T_CONFIRM,
           "lock", "the seen share counts one frame too many"),
    Mutant("confirmation.min_score_inclusive", _CONFIRMATION, "if score < rule.min_score:",
           "if score <= rule.min_score:", _T_CONFIRM, "lock",
           "a mean score of exactly min_score discarded"),
    Mutant("confirmation.min_seen_s_strict", _CONFIRMATION,
           "if enough and seen >= rule.min_seen_s:", "if enough and seen > rule.min_seen_s:",
           _T_CONFIRM, "lock", "evidence over exactly min_seen_s not enough"),
    Mutant("confirmation.min_sightings_minus_one", _CONFIRMATION,
           "enough = len(sightings) >= rule.min_sightings",
           "enough = len(sightings) >= rule.min_sightings - 1", _T_CONFIRM, "lock",
           "confirmed on one sighting fewer than min_sightings"),
    Mutant("confirmation.give_up_inclusive", _CONFIRMATION,
           'if age > rule.give_up_s:\n        return Assessment("discard", f"not confirmed',
           'if age >= rule.give_up_s:\n        return Assessment("discard", f"not confirmed',
           _T_CONFIRM, "lock", "a candidate given up at exactly give_up_s"),
    Mutant("confirmation.fix_error_ignored_in_drift", _CONFIRMATION,
           "sigma_v = max(sigma_fit, sigma_fix) / math.sqrt(spread)",
           "sigma_v = sigma_fit / math.sqrt(spread)", _T_CONFIRM, "lock",
           "a few fixes on a line fake a precise drift (fix errors ignored)"),
    Mutant("candidates.zone_radius_halved", _CANDIDATES,
           "if math.hypot(float(n), float(e)) <= zone[2]:",
           "if math.hypot(float(n), float(e)) <= zone[2] / 2:", _T_ZONES, "delivery",
           "a dismissed zone suppresses only half its radius"),
    Mutant("candidates.zone_north_east_swapped", _CANDIDATES,
           "n, e, _ = geodetic_to_ned(position[0], position[1], 0.0, zone[0], zone[1], 0.0)",
           "n, e, _ = geodetic_to_ned(position[1], position[0], 0.0, zone[0], zone[1], 0.0)",
           _T_ZONES, "delivery", "a position's latitude and longitude swapped in the zone test"),
    Mutant("model.dismiss_radius_not_doubled", _ALERT_MODEL,
           "return max(2.0 * float(error_m), DISMISS_MIN_RADIUS_M)",
           "return max(float(error_m), DISMISS_MIN_RADIUS_M)", _T_ZONES, "delivery",
           "a dismissed zone of one error radius, not two"),
    Mutant("model.dismiss_min_radius_ignored", _ALERT_MODEL,
           "return max(2.0 * float(error_m), DISMISS_MIN_RADIUS_M)",
           "return 2.0 * float(error_m)", _T_ZONES, "delivery",
           "no least radius for a dismissed zone"),
    # -- evaluation: alert scoring ----------------------------------------------------------------
    Mutant("scoring.match_px_exclusive", _SCORING,
           "        d = math.hypot(x - cx, y - cy)\n        if d <= best_d:",
           "        d = math.hypot(x - cx, y - cy)\n        if d < best_d:", _T_SCORING, "metric",
           "a person exactly match_px away not matched"),
    Mutant("scoring.centre_no_half_pixel", _SCORING,
           "return (box[0] + box[2]) / 2 - 0.5, (box[1] + box[3]) / 2 - 0.5",
           "return (box[0] + box[2]) / 2, (box[1] + box[3]) / 2", _T_SCORING, "metric",
           "box centres half a pixel off (edges taken as pixel centres)"),
    Mutant("scoring.gate_ignores_error", _SCORING,
           "gate = max(match_m, 3.0 * (alert.error_m or 0.0))", "gate = match_m", _T_SCORING,
           "metric", "the position match ignores the alert's error"),
    Mutant("scoring.window_one_sided", _SCORING,
           "lo, hi = bisect.bisect_left(times, at - window_s), "
           "bisect.bisect_right(times, at + window_s)",
           "lo, hi = bisect.bisect_left(times, at), bisect.bisect_right(times, at + window_s)",
           _T_SCORING, "metric", "the position match looks only after the lock"),
    Mutant("scoring.view_gap_inclusive", _SCORING,
           "if tid not in last or t - last[tid] > max_gap_s:",
           "if tid not in last or t - last[tid] >= max_gap_s:", _T_SCORING, "metric",
           "a gap of exactly max_gap_s breaks a stretch in view"),
    Mutant("scoring.in_view_strict", _SCORING,
           "in_view = {tid for tid, s in longest.items() if s >= min_view_s}",
           "in_view = {tid for tid, s in longest.items() if s > min_view_s}", _T_SCORING,
           "metric", "a person in view for exactly min_view_s not counted"),
    Mutant("scoring.duplicates_not_counted", _SCORING,
           "            out.duplicates += 1\n", "", _T_SCORING, "metric",
           "duplicate alerts not counted"),
    Mutant("scoring.briefly_seen_counted_found", _SCORING, "out.found = len(found & in_view)",
           "out.found = len(found)", _T_SCORING, "metric",
           "people found though never in view long enough count as found"),
    Mutant("scoring.false_per_minute", _SCORING,
           "return self.false_alerts / (self.flight_s / 3600.0)",
           "return self.false_alerts / (self.flight_s / 60.0)", _T_SCORING, "metric",
           "false alerts per minute reported as per hour"),
    Mutant("scoring.time_to_alert_from_lock_frame", _SCORING,
           "out.time_to_alert_s.append(confirm_t - first[person.track_id])",
           "out.time_to_alert_s.append(confirm_t - frame.sim_time if frame else 0.0)",
           _T_SCORING, "metric", "time to alert measured from the lock, not the first view"),
    # -- mission: the visit plan ---------------------------------------------------------------
    Mutant("visits.group_radius_halved", _VISITS,
           "if _distance_m(first.position, p.position) <= self.group_radius_m)",
           "if _distance_m(first.position, p.position) <= self.group_radius_m / 2)",
           _T_VISITS + ("tests/test_visits.py",), "delivery",
           "targets within the group radius visited separately"),
    Mutant("visits.interval_ignored", _VISITS,
           "return max(0.0, self._last_visit + self.min_interval_s - self.clock())",
           "return 0.0", _T_VISITS + ("tests/test_visits.py",), "delivery",
           "moves sent without the interval between visits"),
]
