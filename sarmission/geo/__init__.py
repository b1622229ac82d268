"""Camera model, pose interpolation, ray-ground geolocation and WGS84 helpers."""
