"""``foxglove_layout.json``: a Foxglove layout for a run's MCAP (Import layout from file).

A 3D panel that follows the ego, with the LiDAR coloured by class, the radar, the boxes
and the static map; an image panel per camera with its 2D boxes drawn on it; the label
table of the current frame.
"""

from __future__ import annotations

from foxglove.layouts import (
    BaseRendererPointCloudTopicSettings,
    BaseRendererSceneUpdateTopicSettings,
    BaseRendererTopicSettings,
    ImageAnnotationSettings,
    ImageConfig,
    ImageModeConfig,
    ImagePanel,
    Layout,
    RawMessagesConfig,
    RawMessagesPanel,
    SplitContainer,
    SplitItem,
    ThreeDeeConfig,
    ThreeDeePanel,
)

from gtgen import topics
from gtgen.frame import FrameRecord

RADAR_COLOUR = "#ff40ff"


def foxglove_layout(
    lidars: list[str], cameras: list[str], radars: list[str], map_vectors: bool = False, occupancy: bool = False
) -> str:
    """The layout as JSON, for a rig with these sensor names (topics as in ``run.mcap``); with
    ``occupancy``, the 3D view shows ``/occupancy`` too."""
    settings: dict[str, BaseRendererTopicSettings] = {
        topics.cloud(name): BaseRendererPointCloudTopicSettings(
            visible=True, color_mode="colormap", color_field="class", color_map="turbo", point_size=2.0
        )
        for name in lidars
    }
    settings |= {
        topics.cloud(name): BaseRendererPointCloudTopicSettings(
            visible=True, color_mode="flat", flat_color=RADAR_COLOUR, point_size=6.0
        )
        for name in radars
    }
    settings |= {
        topics.BOXES: BaseRendererSceneUpdateTopicSettings(visible=True, show_outlines=True),
        topics.MAP: BaseRendererSceneUpdateTopicSettings(visible=True),
    }
    if map_vectors:
        settings[topics.MAP_VECTORS] = BaseRendererSceneUpdateTopicSettings(visible=True)
    if occupancy:
        settings[topics.OCCUPANCY] = BaseRendererSceneUpdateTopicSettings(visible=True)
    scene = ThreeDeePanel(
        title="drive", config=ThreeDeeConfig(topics=settings, follow_tf="ego", follow_mode="follow-pose")
    )
    images = [
        ImagePanel(
            title=name,
            config=ImageConfig(
                image_mode=ImageModeConfig(
                    image_topic=topics.camera(name, "image"),
                    calibration_topic=topics.camera(name, "calibration"),
                    annotations={topics.camera(name, "annotations"): ImageAnnotationSettings(visible=True)},
                )
            ),
        )
        for name in cameras
    ]
    table = RawMessagesPanel(title="labels", config=RawMessagesConfig(topic_path=topics.LABELS))
    side = [*images, table]
    column = SplitContainer(direction="column", items=[SplitItem(proportion=1.0, content=p) for p in side])
    content = SplitContainer(
        direction="row", items=[SplitItem(proportion=0.55, content=scene), SplitItem(proportion=0.45, content=column)]
    )
    return str(Layout(content=content).to_json())


def layout_for(record: FrameRecord) -> str:
    """The layout for the rig of a frame record."""
    names = ([o.spec.name for o in record.lidars], list(record.labels.rig_cameras),
             [o.spec.name for o in record.radars])  # fmt: skip
    return foxglove_layout(*names, map_vectors=record.map is not None, occupancy=record.occupancy is not None)
