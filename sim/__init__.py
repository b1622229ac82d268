"""Replay simulator: synthetic 4K SAR scenes with ground truth, flight telemetry and a MAVLink vehicle."""
