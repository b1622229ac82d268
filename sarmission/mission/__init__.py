"""Mission controller, mission configuration and action policy."""
