"""Flight logs as real drones record them, read into telemetry for offline replay.

One module per format, each read with its ecosystem's library: MAVLink telemetry logs
(:mod:`.tlog`) and ArduPilot DataFlash logs (:mod:`.dataflash`) with pymavlink, PX4 ULog
(:mod:`.ulog`) with pyulog, DJI subtitle sidecars (:mod:`.dji_srt`) and DJI image EXIF/XMP
(:mod:`.dji_images`) with exifread. Each gives a :class:`~.model.FlightLog` in the log's own
clock; :mod:`.align` maps frames onto that clock and :mod:`.feed` pushes the samples into a
:class:`~sarmission.mavlink.telemetry.TelemetryBuffer`. :func:`~.detect.open_flight_log`
picks the reader from the file's content. See ``docs/flightlogs.md``.
"""

from sarmission.flightlog.model import FlightLog, FlightLogError

__all__ = ["FlightLog", "FlightLogError"]
