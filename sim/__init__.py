"""Replay simulator: synthetic SAR scenes with ground truth, flight telemetry, MAVLink vehicle."""
