"""Dataset formats (COCO video / SeaDronesSee, MOT text, YOLO text) and frame sources."""

from sarmission.data.coco_video import (
    Annotation,
    Category,
    DatasetFormatError,
    FrameTelemetry,
    ImageRecord,
    Video,
    VideoDataset,
    parse_telemetry,
    read_coco_video,
    write_coco_video,
)
from sarmission.data.frames import Frame, FrameSource, FrameSourceError, open_frame_source
from sarmission.data.mot import MotRow, read_mot, write_mot
from sarmission.data.yolo import YoloBox, read_yolo, write_yolo, xyxy_to_yolo, yolo_to_xyxy

__all__ = [
    "Annotation",
    "Category",
    "DatasetFormatError",
    "Frame",
    "FrameSource",
    "FrameSourceError",
    "FrameTelemetry",
    "ImageRecord",
    "MotRow",
    "Video",
    "VideoDataset",
    "YoloBox",
    "open_frame_source",
    "parse_telemetry",
    "read_coco_video",
    "read_mot",
    "read_yolo",
    "write_coco_video",
    "write_mot",
    "write_yolo",
    "xyxy_to_yolo",
    "yolo_to_xyxy",
]
