"""The topics of ``run.mcap`` and of the live view, named in one place.

Every frame: ``/tf`` (map -> ego -> each sensor); each LiDAR's cloud on ``/<name>`` (and
``/<name>/deskewed`` where it deskews) and each radar's on ``/<name>``; each camera's
``/<name>/image``, ``depth``, ``instance``, ``class``, ``calibration`` and ``annotations``;
``/gt/boxes``; where the run makes them, ``/occupancy``, ``/map/vectors`` and ``/gt/events``;
then ``/gt/labels``. Once, before the first frame: ``/map``, the static world.
:func:`gtgen.sinks.mcap_sink.planned_topics` lists a rig's topics with their schemas.
"""

from __future__ import annotations

TF = "/tf"
MAP = "/map"
MAP_VECTORS = "/map/vectors"
BOXES = "/gt/boxes"
LABELS = "/gt/labels"
EVENTS = "/gt/events"  # hazard events under way (runs with hazards)
OCCUPANCY = "/occupancy"
CAMERA_IMAGES = ("image", "depth", "instance", "class")
"""A camera's image topics, in the order they are written."""


def cloud(sensor_name: str) -> str:
    """A LiDAR's or a radar's point cloud."""
    return f"/{sensor_name}"


def deskewed(lidar_name: str) -> str:
    """A LiDAR's cloud with its points moved to the frame's time."""
    return f"{cloud(lidar_name)}/deskewed"


def camera(camera_name: str, stream: str) -> str:
    """One of a camera's topics: an image of :data:`CAMERA_IMAGES`, ``calibration`` or ``annotations``."""
    return f"/{camera_name}/{stream}"
