"""``sarmission replay INPUT``: the mission controller offline on a video, image folder or COCO
video dataset, with telemetry from the dataset's ``meta`` or the mission's simulated flight."""

from __future__ import annotations

import argparse
import tempfile
import time
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING

from sarmission.commands.mission_options import (
    add_mission_options,
    build_detector,
    build_recorder,
    load_mission_from_args,
)

if TYPE_CHECKING:
    import numpy as np

    from sarmission.data.coco_video import FrameTelemetry

#: (frame index, time s, image, per-frame dataset telemetry or None)
ReplayFrame = tuple[int, float, "np.ndarray", "FrameTelemetry | None"]


def add_parser(sub: argparse._SubParsersAction) -> None:
    """Register ``replay``."""
    parser = sub.add_parser(
        "replay",
        help="run the mission controller offline on a video, image folder or COCO dataset",
        description="Detection, tracking, lock, geolocation and alerts on recorded frames, "
        "without MAVLink. Telemetry comes from the dataset's per-image meta (lat/lon/altitude/"
        "gimbal pitch/heading) when present, else from the mission's simulated flight.",
    )
    parser.add_argument("input", help="video file, image folder or COCO video annotations (.json)")
    parser.add_argument("--fps", type=float, default=30.0,
                        help="frame rate of an image folder or dataset (default: %(default)s)")
    parser.add_argument("--video-id", type=int, default=None,
                        help="which video of a COCO dataset (default: the first)")
    parser.add_argument("--telemetry", choices=("auto", "meta", "flight"), default="auto",
                        help="telemetry source: the dataset's meta, the mission's simulated "
                        "flight, or auto (meta when the dataset has positions; default)")
    parser.add_argument("--alerts-db", default=None,
                        help="alert store file (default: a temporary one)")
    add_mission_options(parser)
    parser.set_defaults(func=run)


def _dataset_frames(path: Path, video_id: int | None, fps: float,
                    counters: dict[str, int]) -> tuple[Iterator[ReplayFrame], int, bool]:
    from sarmission.data.coco_video import read_coco_video
    from sarmission.data.sequence import iter_sequence, sequence_ids, sequence_images
    from sarmission.mission.replay_telemetry import has_position

    dataset = read_coco_video(path)
    ids = sequence_ids(dataset)
    vid = ids[0] if video_id is None else video_id
    if vid not in ids:
        raise ValueError(f"{path}: no video {video_id} (videos: {ids})")
    images = sequence_images(dataset, vid)
    with_meta = any(has_position(im.telemetry) for im in images)

    def frames() -> Iterator[ReplayFrame]:
        for n, item in enumerate(iter_sequence(dataset, vid, counters)):
            index = item.image.frame_index if item.image.frame_index is not None else n
            yield index, index / fps, item.frame_bgr, item.image.telemetry

    return frames(), len(images), with_meta


def _file_frames(path: Path, fps: float) -> tuple[Iterator[ReplayFrame], int | None, object]:
    from sarmission.data.frames import open_frame_source

    source = open_frame_source(path, fps)

    def frames() -> Iterator[ReplayFrame]:
        for frame in source:
            yield frame.index, frame.timestamp_s, frame.image_bgr, None

    return frames(), source.length, source


def run(args: argparse.Namespace) -> int:
    from tqdm import tqdm

    from sarmission.alerts.store import AlertStore
    from sarmission.mission.controller import MissionController
    from sarmission.mission.live import telemetry_buffer
    from sarmission.mission.replay_telemetry import push_flight_state, push_frame_telemetry

    mission = load_mission_from_args(args)
    path = Path(args.input)
    if args.fps <= 0:
        raise ValueError(f"--fps must be positive, got {args.fps}")
    counters: dict[str, int] = {}
    file_source = None
    if path.suffix.lower() == ".json":
        frames, total, with_meta = _dataset_frames(path, args.video_id, args.fps, counters)
    else:
        frames, total, file_source = _file_frames(path, args.fps)
        with_meta = False
    if args.telemetry == "meta" and not with_meta:
        raise ValueError(f"{path}: no per-frame telemetry (meta with latitude, longitude and "
                         "altitude) to replay; use --telemetry flight")
    use_meta = with_meta and args.telemetry != "flight"
    flight = None
    if not use_meta:
        from sim.flight import Flight

        flight = Flight(mission)
    detector, model_note = build_detector(args, mission)
    recorder = build_recorder(args)
    print(f"replay of {path} ({total if total is not None else '?'} frames), mission "
          f"'{mission.name}', telemetry: "
          f"{'dataset meta' if use_meta else 'simulated flight of the mission'}")
    print(model_note)

    with tempfile.TemporaryDirectory() as tmp:
        store = AlertStore(args.alerts_db or Path(tmp) / "alerts.db")
        buffer = telemetry_buffer(mission)
        start_posix = time.time()
        controller = MissionController(mission, detector, buffer, store, recorder=recorder,
                                       mission_id=args.mission_id,
                                       to_posix=lambda t: start_posix + t,
                                       console=tqdm.write)
        started = time.monotonic()
        n = 0
        try:
            limit = args.max_frames
            bar_total = min(total, limit) if total is not None and limit else (total or limit)
            for index, t, image, meta in tqdm(frames, total=bar_total, unit="frame",
                                              desc="replay", leave=False):
                if (limit is not None and n >= limit) or (
                        args.duration is not None and t >= args.duration):
                    break
                if use_meta and meta is not None:
                    push_frame_telemetry(buffer, t, meta)
                elif flight is not None:
                    push_flight_state(buffer, t, flight.state_at(t), mission.area.home)
                controller.process(index, t, image)
                n += 1
        finally:
            wall = time.monotonic() - started
            if recorder is not None:
                recorder.close()
            store.close()
        unreadable = counters.get("skipped", 0) + (file_source.skipped if file_source else 0)
        print(controller.summary(wall))
        if unreadable:
            print(f"unreadable frames skipped by the reader: {unreadable}")
        if recorder is not None and recorder.path is not None:
            print(f"wrote {recorder.path}")
        if args.alerts_db:
            print(f"alerts in {args.alerts_db}")
    return 0
