"""rerun logging of frames, proposals, detections, tracks and targets."""
