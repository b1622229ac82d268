"""sarmission: onboard search-and-rescue mission software for UAV companion computers."""

__version__ = "0.1.0"
