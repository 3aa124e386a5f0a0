"""Sensors: camera, LiDAR and radar frames by raycasting one scene per frame."""
