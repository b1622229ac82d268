"""The detector's crops sized to the person from the camera's pose, live and over a dataset.

:class:`~sarmission.perception.mitenet.MiteNet` grows a proposal's crops where a person would
span more than its box (``process(person_px=...)``); the pixels a person spans come from the
camera model and a pose (:func:`~sarmission.geo.person_pixels.person_pixels`). Live, the pose
is the adopted autopilot's current one, and without it crops are cut as at the survey's ranges
(a stale or unknown pose never sizes a crop). Over a dataset, each frame's pose is read from its
``meta`` with the file's conventions, and the lens from the video's ``hfov_deg`` or the caller's.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from sarmission.data.coco_video import ImageRecord, VideoDataset
from sarmission.data.meta_conventions import MetaPose, dataset_conventions, meta_pose
from sarmission.geo.camera import CameraIntrinsics
from sarmission.geo.geolocate import PlatformPose
from sarmission.geo.person_pixels import person_pixels
from sarmission.mission.replay_telemetry import frame_pose

PersonPixels = Callable[[np.ndarray], np.ndarray]

#: The default ``[detector] person_m``: a swimmer's head and shoulders, the part of a person in
#: the water seen from above. People at the survey's 75-120 m span 12-13 px of a 3840 px frame
#: through a 70-80 degree lens (docs/box_colours.md), 0.45-0.6 m.
DEFAULT_PERSON_M = 0.45


def pose_person_px(
    intrinsics: CameraIntrinsics,
    pose: Any,
    person_m: float,
    ground_below_home_m: float | None = 0.0,
) -> PersonPixels | None:
    """The pixels a person ``person_m`` across spans at image points seen from ``pose``; None
    (crops as at the survey's ranges) when ``person_m`` is 0, the pose is not a current
    :class:`PlatformPose` or the ground plane is unknown."""
    if person_m <= 0.0 or not isinstance(pose, PlatformPose) or ground_below_home_m is None:
        return None
    ground = float(ground_below_home_m)

    def pixels(centres: np.ndarray) -> np.ndarray:
        return person_pixels(centres, intrinsics, pose, person_m, ground)

    return pixels


def dataset_person_px(
    dataset: VideoDataset,
    person_m: float,
    hfov_deg: float | None = None,
    conventions: str | None = None,
) -> Callable[[ImageRecord], PersonPixels | None]:
    """For each image of ``dataset``: the pixels a person spans at its points, from the image's
    ``meta`` read with the file's conventions (``conventions``: as ``sarmission replay``'s
    option) and the lens ``hfov_deg`` (None: the video's ``hfov_deg``); None for an image
    without a placed camera or a lens. Home is each frame's own position at take-off height."""
    if person_m <= 0.0:
        return lambda image: None
    rules = dataset_conventions(dataset, conventions)
    lenses = {v.id: v.extra.get("hfov_deg") for v in dataset.videos}
    intrinsics: dict[tuple[int, int, float], CameraIntrinsics] = {}  # one per lens and size

    def of(image: ImageRecord) -> PersonPixels | None:
        hfov = hfov_deg if hfov_deg is not None else lenses.get(image.video_id)
        if not isinstance(hfov, int | float) or not 0.0 < float(hfov) < 180.0:
            return None
        placed = meta_pose(image.telemetry, rules)
        if not isinstance(placed, MetaPose):
            return None
        key = (image.width, image.height, float(hfov))
        if key not in intrinsics:
            intrinsics[key] = CameraIntrinsics.from_hfov(*key)
        return pose_person_px(intrinsics[key], frame_pose(placed), person_m)

    return of
