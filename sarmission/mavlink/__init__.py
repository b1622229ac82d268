"""MAVLink connection, telemetry buffer, commands and mission upload."""
