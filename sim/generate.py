"""Render a scenario along a survey flight into a video or image folder plus COCO-video GT.

Output in ``out_dir``: ``<name>.mp4`` (``video=True``, mp4v) or ``<name>/NNNNNN.jpg``, and
``<name>.json`` in the SeaDronesSee / COCO video layout (see :mod:`sarmission.data.coco_video`):
one video (with ``file_name`` of the MP4 when there is one), an image per frame with flight
telemetry in ``meta`` (SeaDronesSee MOT keys and conventions: degrees, gimbal pitch positive below
the horizon as ``info.meta_conventions`` states, metres above home, m/s with x north, y east,
z down, ``time`` seconds since the flight start), and an annotation per visible object with
its ``track_id``, exact ``bbox`` and true ``gt_lat`` / ``gt_lon``; ``visibility``, ``is_target``
and ``position_ned`` are kept as extra keys. Categories are :data:`sim.scene.CATEGORIES`; only
``swimmer`` and ``swimmer_with_life_jacket`` are maritime detector classes (``person`` is a
target on land; every other category is a distractor).
"""

from __future__ import annotations

import dataclasses
import math
from pathlib import Path

import cv2
import numpy as np
from tqdm import tqdm

from sarmission.data.coco_video import (
    Annotation,
    Category,
    ImageRecord,
    Video,
    VideoDataset,
    read_coco_video,
    write_coco_video,
)
from sarmission.data.meta_conventions import DEPRESSION, INFO_KEY
from sarmission.mission.config import MissionConfig
from sim.flight import Flight, VehicleState
from sim.render import ObjectAnnotation, SceneRenderer
from sim.scene import CATEGORIES, TARGET_CATEGORIES, Scenario
from sim.truth_frames import ned_to_geodetic


def frame_meta(state: VehicleState, home: tuple[float, float, float]) -> dict[str, float]:
    """SeaDronesSee-style telemetry of one frame from the exact vehicle state."""
    lat, lon, _ = ned_to_geodetic(*state.position_ned, *home)
    v = state.velocity_ned
    gimbal_heading = state.gimbal_yaw + (state.yaw if state.gimbal_frame != "earth" else 0.0)
    return {
        "gps_latitude": float(lat),
        "gps_longitude": float(lon),
        "altitude": float(-state.position_ned[2]),
        "gimbal_pitch": -math.degrees(state.gimbal_pitch),  # SeaDronesSee: 90 straight down
        "gimbal_roll": math.degrees(state.gimbal_roll),
        "gimbal_heading": math.degrees(gimbal_heading) % 360.0,
        "compass_heading": math.degrees(state.yaw) % 360.0,
        "speed": float(np.linalg.norm(v)),
        "xspeed": float(v[0]),
        "yspeed": float(v[1]),
        "zspeed": float(v[2]),
        "time": float(state.t),
    }


def _coco_annotation(ann: ObjectAnnotation, ann_id: int, image_id: int) -> Annotation:
    x0, y0, x1, y1 = ann.bbox_xyxy
    return Annotation(
        id=ann_id,
        image_id=image_id,
        category_id=ann.category_id,
        bbox=(round(x0, 3), round(y0, 3), round(x1 - x0, 3), round(y1 - y0, 3)),
        track_id=ann.track_id,
        video_id=1,
        area=round(ann.area, 3),
        gt_lat=ann.lat,
        gt_lon=ann.lon,
        extra={
            "visibility": round(ann.visibility, 3),
            "is_target": ann.is_target,
            "position_ned": [round(v, 3) for v in ann.position_ned],
        },
    )


def generate_sequence(
    scenario: Scenario,
    mission_or_flight: MissionConfig | Flight,
    frames: int,
    size: tuple[int, int] = (3840, 2160),
    seed: int = 0,
    out_dir: str | Path = ".",
    fps: float = 30.0,
    video: bool = True,
    progress: bool = True,
    name: str | None = None,
    start_s: float = 0.0,
    image_ext: str = ".jpg",
) -> Path:
    """Render ``frames`` frames at ``fps`` from ``start_s`` seconds into the flight.

    ``mission_or_flight`` is a :class:`MissionConfig` (flown by :class:`Flight` with ``seed``) or
    a ready :class:`Flight`; its camera, scaled to ``size`` = (width, height), is the renderer's.
    Returns the path of the annotation JSON.
    """
    if isinstance(mission_or_flight, Flight):
        flight = mission_or_flight
    else:
        flight = Flight(mission_or_flight, seed=seed)
    mission = flight.mission
    width, height = size
    intr = mission.camera.intrinsics().scaled(width, height)
    home = mission.area.home
    renderer = SceneRenderer(scenario, intr, home=home)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    name = name or f"{mission.name}_{scenario.kind}_{scenario.seed}"
    video_extra: dict[str, object] = {"width": width, "height": height, "fps": fps}
    writer = None
    if video:
        video_extra["file_name"] = f"{name}.mp4"
        writer = cv2.VideoWriter(
            str(out / f"{name}.mp4"), cv2.VideoWriter_fourcc(*"mp4v"), fps, (width, height)
        )
        if not writer.isOpened():
            raise OSError(f"cannot open a video writer for {out / f'{name}.mp4'}")
    else:
        (out / name).mkdir(exist_ok=True)
    images: list[ImageRecord] = []
    annotations: list[Annotation] = []
    try:
        for i in tqdm(range(frames), desc=name, disable=not progress, unit="frame"):
            t = start_s + i / fps
            state = flight.state_at(t)
            frame, anns = renderer.render(t, state.camera_pose())
            file_name = f"{name}/{i:06d}{image_ext}"
            if writer is not None:
                writer.write(frame)
            elif not cv2.imwrite(str(out / file_name), frame):
                raise OSError(f"cannot write {out / file_name}")
            images.append(
                ImageRecord(
                    id=i + 1,
                    file_name=file_name,
                    height=height,
                    width=width,
                    video_id=1,
                    frame_index=i,
                    meta=frame_meta(state, home),
                )
            )
            for ann in anns:
                annotations.append(_coco_annotation(ann, len(annotations) + 1, i + 1))
    finally:
        if writer is not None:
            writer.release()
    categories = [
        Category(cid, cname, "person" if cname in TARGET_CATEGORIES else "object")
        for cname, cid in CATEGORIES.items()
    ]
    dataset = VideoDataset(
        videos=[Video(1, name, video_extra)],
        images=images,
        annotations=annotations,
        categories=categories,
        info={
            "description": f"sarmission synthetic {scenario.kind} scene",
            "seed": scenario.seed,
            "sea_state": scenario.sea_state,
            "fps": fps,
            "start_s": start_s,
            "home": list(home),
            INFO_KEY: {"gimbal_pitch": DEPRESSION},
        },
    )
    path = out / f"{name}.json"
    write_coco_video(dataset, path)
    return path


def merge_datasets(datasets: list[VideoDataset], info: dict | None = None) -> VideoDataset:
    """One dataset holding the videos of several, with image/annotation/video ids renumbered.

    Categories must agree (they do for every simulator output); video ``file_name`` entries
    are kept, so the merged file must sit in the same folder as the videos.
    """
    if not datasets:
        raise ValueError("nothing to merge")
    videos, images, annotations = [], [], []
    for dataset in datasets:
        if [c.id for c in dataset.categories] != [c.id for c in datasets[0].categories]:
            raise ValueError("datasets with different categories cannot be merged")
        video_ids = {v.id: len(videos) + i + 1 for i, v in enumerate(dataset.videos)}
        image_ids = {im.id: len(images) + i + 1 for i, im in enumerate(dataset.images)}
        videos += [dataclasses.replace(v, id=video_ids[v.id]) for v in dataset.videos]
        images += [
            dataclasses.replace(im, id=image_ids[im.id], video_id=video_ids[im.video_id])
            for im in dataset.images
        ]
        annotations += [
            dataclasses.replace(
                a,
                id=len(annotations) + i + 1,
                image_id=image_ids[a.image_id],
                video_id=video_ids.get(a.video_id, a.video_id),
            )
            for i, a in enumerate(dataset.annotations)
        ]
    return VideoDataset(
        videos=videos,
        images=images,
        annotations=annotations,
        categories=datasets[0].categories,
        info=info or datasets[0].info,
    )


def generate_split(
    preset_name: str,
    sequences: int,
    frames: int,
    out_dir: str | Path,
    size: tuple[int, int] = (3840, 2160),
    fps: float = 30.0,
    first_start_s: float = 5.0,
    spacing_s: float = 15.0,
    video: bool = True,
    progress: bool = True,
    seed: int | None = None,
) -> Path:
    """Render ``sequences`` clips of a preset along its flight and merge them into one file.

    Clip ``i`` starts ``first_start_s + i * spacing_s`` seconds into the flight (the world and the
    flight share the preset's seed, or ``seed``), so the clips see different stretches of the
    search area.
    Returns ``<out_dir>/<preset_name>.json``.
    """
    from sim.scenarios import preset

    if sequences < 1:
        raise ValueError(f"sequences must be at least 1, got {sequences}")
    chosen = preset(preset_name)
    scenario = chosen.scenario if seed is None else dataclasses.replace(chosen.scenario, seed=seed)
    out = Path(out_dir)
    parts = []
    for i in range(sequences):
        path = generate_sequence(
            scenario,
            chosen.mission,
            frames,
            size=size,
            seed=scenario.seed,
            out_dir=out,
            fps=fps,
            video=video,
            progress=progress,
            name=f"{preset_name}_{i:02d}",
            start_s=first_start_s + i * spacing_s,
        )
        parts.append(read_coco_video(path))
        path.unlink()
    merged = merge_datasets(
        parts, info={**parts[0].info, "preset": preset_name, "sequences": sequences}
    )
    path = out / f"{preset_name}.json"
    write_coco_video(merged, path)
    return path
