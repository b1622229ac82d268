"""``sarmission replay INPUT``: the mission controller offline on a video, image folder or COCO
video dataset, with telemetry from a real flight log (``--telemetry FILE``, aligned with the
footage), the dataset's ``meta``, the mission's simulated flight when asked (``--telemetry
sim``), or none: then alerts carry frame, time and pixel and no position. ``--dem`` places
pixels on terrain, ``--report DIR`` writes the post-flight report."""

from __future__ import annotations

import argparse
import math
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, Any

from sarmission.commands.cli_helpers import positive_rate
from sarmission.commands.mission_options import (
    add_mission_options,
    build_detector,
    build_recorder,
    load_mission_from_args,
)
from sarmission.commands.progress import add_progress_option, progress_for
from sarmission.data.frames import MAX_FPS, MIN_FPS

if TYPE_CHECKING:
    import numpy as np

    from sarmission.data.meta_conventions import MetaConventions, MetaPose, NoMetaPose
    from sarmission.yuv import YuvImage

#: (frame index, time s, image, the frame's placement from dataset meta, or why none, or None)
ReplayFrame = tuple[int, float, "np.ndarray | YuvImage", "MetaPose | NoMetaPose | None"]


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``replay``."""
    parser = sub.add_parser(
        "replay",
        help="run the mission controller offline on a video, image folder or COCO dataset",
        description="Detection, tracking, lock, geolocation and alerts on recorded frames, "
        "without MAVLink. Telemetry comes from a flight log (--telemetry FILE: MAVLink tlog, "
        "ArduPilot DataFlash .bin/.log, PX4 .ulg, DJI .SRT, a folder of DJI JPEGs), the "
        "dataset's per-image meta, or the mission's simulated flight (--telemetry sim); "
        "without any, alerts have no position.",
    )
    parser.add_argument("input", help="video file, image folder or COCO video annotations (.json)")
    parser.add_argument(
        "--fps",
        type=positive_rate,
        default=30.0,
        help="frame rate of an image folder or dataset (default: %(default)s)",
    )
    parser.add_argument(
        "--video-id",
        type=int,
        default=None,
        help="which video of a COCO dataset (default: the first)",
    )
    parser.add_argument(
        "--telemetry",
        default="auto",
        metavar="auto|none|meta|sim|FILE",
        help="telemetry: a flight log FILE (format found from its content), "
        "meta (the dataset's), sim (the mission's simulated flight: made-up "
        "positions, for rehearsal), none, or auto: meta when the dataset has "
        "positions, else a DJI .SRT beside the video, else none (default)",
    )
    parser.add_argument(
        "--meta-pitch",
        default="auto",
        choices=("auto", "depression", "elevation"),
        help="how a dataset's meta gives the gimbal pitch: depression (positive "
        "below the horizon, 90 straight down: SeaDronesSee), elevation (negative "
        "below the horizon: DJI logs, MAVLink) or auto: as the file states, else "
        "from the signs of its pitches; a file with both signs is refused "
        "(default: %(default)s)",
    )
    parser.add_argument(
        "--time-offset",
        type=float,
        default=None,
        metavar="S",
        help="the flight log's time (its own clock, as printed) at which the "
        "video starts; default: from camera triggers or the video's creation "
        "time",
    )
    parser.add_argument(
        "--takeoff-alt",
        type=float,
        default=None,
        metavar="M",
        help="dataset meta: the take-off's altitude above sea level in metres (meta heights "
        "are above take-off); needed for --dem and the mission's ground_alt_m, else the "
        "ground plane is the take-off's",
    )
    parser.add_argument(
        "--dem",
        default=None,
        metavar="FILE",
        help="terrain for a land search: a GeoTIFF DEM or SRTM .hgt tile; pixels "
        "are placed where their ray meets it instead of a plane at home altitude",
    )
    parser.add_argument(
        "--dem-sigma",
        type=float,
        default=None,
        metavar="M",
        help="1-sigma vertical accuracy of the DEM in metres (default: 6 for "
        "SRTM, 2 for a GeoTIFF)",
    )
    parser.add_argument(
        "--report",
        default=None,
        metavar="DIR",
        help="write the post-flight report (HTML with an offline map, KML, GeoJSON, CSV) into DIR",
    )
    parser.add_argument(
        "--alerts-db", default=None, help="alert store file (default: a temporary one)"
    )
    add_progress_option(parser)
    add_mission_options(parser)
    parser.set_defaults(func=run)


def _dataset_frames(
    path: Path,
    video_id: int | None,
    fps: float,
    counters: dict[str, int],
    pitch_option: str | None = None,
) -> tuple[Iterator[ReplayFrame], int, bool, MetaConventions | str]:
    """The dataset's frames with each one's placement from meta, whether any frame has one,
    and the file's meta conventions (or the line saying why the meta cannot be read)."""
    from sarmission.data.coco_video import read_coco_video
    from sarmission.data.meta_conventions import (
        ConventionError,
        MetaPose,
        dataset_conventions,
        meta_pose,
    )
    from sarmission.data.sequence import iter_sequence, sequence_ids, sequence_images

    dataset = read_coco_video(path)
    ids = sequence_ids(dataset)
    vid = ids[0] if video_id is None else video_id
    if vid not in ids:
        raise ValueError(f"{path}: no video {video_id} (videos: {ids})")
    images = sequence_images(dataset, vid)
    try:
        conventions: MetaConventions | str = dataset_conventions(dataset, pitch_option)
    except ConventionError as exc:
        conventions = str(exc)
    poses = (
        {im.id: meta_pose(im.telemetry, conventions) for im in images}
        if not isinstance(conventions, str)
        else {}
    )
    with_meta = any(isinstance(p, MetaPose) for p in poses.values())

    def frames() -> Iterator[ReplayFrame]:
        for n, item in enumerate(iter_sequence(dataset, vid, counters)):
            index = item.image.frame_index if item.image.frame_index is not None else n
            yield index, index / fps, item.frame_bgr, poses.get(item.image.id)

    return frames(), len(images), with_meta, conventions


def _file_frames(path: Path, fps: float) -> tuple[Iterator[ReplayFrame], int | None, object]:
    from sarmission.data.frames import open_frame_source

    # The decoder's YUV planes, as `detect` and `run --video` read a file: the same footage
    # gives the same detections at the desk as on the drone.
    source = open_frame_source(path, fps, yuv=True)

    def frames() -> Iterator[ReplayFrame]:
        for frame in source:
            yield frame.index, frame.timestamp_s, frame.image, None

    return frames(), source.length, source


def _image_names(file_source: object) -> list[str]:
    """File names of an image folder's frames in order ([] for a video)."""
    return [p.name for p in getattr(file_source, "files", [])]


def _ground_model(args: argparse.Namespace) -> object | None:
    if args.dem is None:
        return None
    from sarmission.geo.terrain import TerrainGround, read_dem

    dem = read_dem(args.dem, args.dem_sigma)
    print(
        f"terrain: {dem.source}, {dem.resolution_m:.1f} m cells, vertical 1-sigma "
        f"{dem.vertical_sigma_m:g} m"
    )
    return TerrainGround(dem)


def _footage(
    args: argparse.Namespace, path: Path, counters: dict[str, int]
) -> tuple[Iterator[ReplayFrame], int | None, bool, MetaConventions | str | None, Any]:
    """The input's frames, their count, whether dataset meta places any, the meta conventions
    (or why they cannot be read) and the file source (None for a dataset)."""
    if path.suffix.lower() == ".json":
        frames, total, with_meta, conventions = _dataset_frames(
            path, args.video_id, args.fps, counters, args.meta_pitch
        )
        return frames, total, with_meta, conventions, None
    frames, count, file_source = _file_frames(path, args.fps)
    return frames, count, False, None, file_source


def _print_outcome(summary: str, unreadable: int, recorder: Any, alerts_db: str | None) -> None:
    """The controller's summary and what the replay wrote."""
    print(summary)
    if unreadable:
        print(f"unreadable frames skipped by the reader: {unreadable}")
    if recorder is not None and recorder.path is not None:
        print(f"wrote {recorder.path}")
    if alerts_db:
        print(f"alerts in {alerts_db}")


#: ``--telemetry`` values that name no file.
TELEMETRY_KEYWORDS = ("auto", "none", "meta", "sim")


def check_telemetry_args(telemetry: str, time_offset: float | None) -> None:
    """ValueError, before any frame is read, for a ``--telemetry`` file that is not there (a
    typo would otherwise cost a whole replay without positions) or an offset that is no
    number of seconds. A log that is there but cannot be believed is refused later, with its
    reason, and the replay goes on without positions."""
    if telemetry not in TELEMETRY_KEYWORDS and not Path(telemetry).exists():
        raise ValueError(
            f"--telemetry {telemetry}: no such file (a flight log, or one of "
            f"{', '.join(TELEMETRY_KEYWORDS)})"
        )
    if time_offset is not None and not math.isfinite(time_offset):
        raise ValueError(f"--time-offset must be a number of seconds, got {time_offset}")


def run(args: argparse.Namespace) -> int:
    from sarmission.alerts.store import AlertStore
    from sarmission.data.frames import Frame
    from sarmission.mission.controller import MissionController
    from sarmission.mission.live import telemetry_buffer
    from sarmission.mission.replay_telemetry import meta_ground, telemetry_source
    from sarmission.mission.session_runner import SessionRunner

    mission = load_mission_from_args(args)
    path = Path(args.input)
    if not (math.isfinite(args.fps) and MIN_FPS <= args.fps <= MAX_FPS):  # without the parser
        raise ValueError(f"--fps must be from {MIN_FPS:g} to {MAX_FPS:g}, got {args.fps}")
    check_telemetry_args(args.telemetry, args.time_offset)
    counters: dict[str, int] = {}
    frames, total, with_meta, conventions, file_source = _footage(args, path, counters)
    names = _image_names(file_source)
    source = telemetry_source(
        args.telemetry,
        input_path=path,
        is_video=file_source is not None and not names,
        names=names,
        fps=args.fps,
        with_meta=with_meta,
        offset_s=args.time_offset,
        duration_s=total / getattr(file_source, "fps", args.fps) if total else None,
        mission=mission,
        meta_conventions=conventions,
    )
    mission = meta_ground(source, mission, args.takeoff_alt, args.dem is not None)
    ground_model = _ground_model(args)
    detector, model_note = build_detector(args, mission)
    recorder = build_recorder(args)
    print(
        f"replay of {path} ({total if total is not None else '?'} frames), mission "
        f"'{mission.name}', telemetry: {source.description}"
    )
    for line in source.lines:
        print(f"  {line}")
    if source.kind != "none":
        print(
            f"camera: {mission.camera.describe()} (the mission's [camera], scaled to the "
            "frames; a lens other than the footage's misplaces every position)"
        )
    print(model_note)
    frame_times: dict[int, tuple[float, float]] = {}  # frame index -> (footage t, clock t)

    with tempfile.TemporaryDirectory() as tmp:
        db_path = Path(args.alerts_db or Path(tmp) / "alerts.db")
        store = AlertStore(db_path)
        buffer = source.buffer(lambda: telemetry_buffer(mission))
        start_posix = time.time()
        utc = source.utc_offset_s
        limit = args.max_frames
        bar_total = min(total, limit) if total is not None and limit else (total or limit)
        bar = progress_for(args, "replay", bar_total)
        controller = MissionController(
            mission,
            detector,
            buffer,
            store,
            recorder=recorder,
            mission_id=args.mission_id,
            to_posix=(lambda t: t + utc) if utc is not None else (lambda t: start_posix + t),
            console=bar.write,
            ground_model=ground_model,
        )

        def stamped() -> Iterator[Frame]:
            """The footage up to --duration, each frame on the telemetry's clock and its meta
            given to the buffer first."""
            for index, t, image, meta in frames:
                if args.duration is not None and t >= args.duration:
                    return
                stamp = source.timestamp(t, names[index] if index < len(names) else None)
                frame_times[index] = (t, stamp)
                source.before(buffer, stamp, meta, mission.area.home)
                yield Frame.of(index, stamp, image)

        started = time.monotonic()
        runner = SessionRunner(controller, on_frame=lambda: bar.update(1))
        try:
            runner.run(stamped(), max_frames=limit)
        finally:
            bar.close()
            wall = time.monotonic() - started
            if recorder is not None:
                recorder.close()
            store.close()
        unreadable = counters.get("skipped", 0) + (
            file_source.skipped if file_source is not None else 0
        )
        _print_outcome(controller.summary(wall), unreadable, recorder, args.alerts_db)
        if args.report:
            _write_report(args, db_path, controller, source, frame_times, path)
    if controller.stats.frames == 0:
        raise ValueError(
            f"{path}: no frame could be processed ({_why_none(runner, controller, unreadable)})"
        )
    return 0


def _why_none(runner: Any, controller: Any, unreadable: int) -> str:
    """Why a replay processed no frame: how many it found and rejected, and why (the
    controller's skip reasons), how many the reader could not read; or that it found none."""
    parts = []
    skipped = controller.stats.skipped
    if runner.frames_read:
        reasons = ", ".join(f"{n} {why}" for why, n in skipped.most_common())
        rejected = f", all rejected: {reasons}" if reasons else ""
        parts.append(f"{runner.frames_read} found{rejected}")
    if unreadable:
        parts.append(f"{'all ' if not parts else ''}{unreadable} unreadable")
    return "; ".join(parts) or "none found"


def _write_report(
    args: argparse.Namespace,
    db_path: Path,
    controller: Any,
    source: Any,
    frame_times: dict[int, tuple[float, float]],
    path: Path,
) -> None:
    """The post-flight report of this replay: every alert the store holds for the mission."""
    from sarmission.alerts.report import ReportInput, write_report
    from sarmission.alerts.store import AlertStore

    with AlertStore(db_path) as store:
        alerts = store.list(mission_id=controller.mission_id)
    track = source.flown
    written = write_report(
        Path(args.report),
        ReportInput(
            title=f"sarmission replay of {path.name}",
            alerts=alerts,
            track=track,
            frame_times={k: v[0] for k, v in frame_times.items()},
            facts=[
                ("footage", str(path)),
                ("telemetry", source.description),
                *(("", line) for line in source.lines),
                ("summary", controller.summary()),
            ],
        ),
    )
    for out in written:
        print(f"wrote {out}")
