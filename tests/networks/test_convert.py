"""Any OpenDRIVE file in: the quirks of real files, and one clear line for a rejected one."""

from pathlib import Path

import pytest
import sumolib

from networks.convert import conversion_notice, import_opendrive, sidewalks_on_driving_lanes
from networks.errors import NetconvertError
from networks.world import build_world, load_net

XODR = Path(__file__).resolve().parents[1] / "data" / "xodr"


def _convert(name: str) -> sumolib.net.Net:
    return load_net(import_opendrive(XODR / name))


def _driving_lanes(net: sumolib.net.Net) -> list[sumolib.net.lane.Lane]:
    return [lane for e in _edges(net) for lane in e.getLanes() if lane.allows("passenger")]


def _edges(net: sumolib.net.Net) -> list[sumolib.net.edge.Edge]:
    return [e for e in net.getEdges(withInternal=False) if not e.getFunction()]


@pytest.mark.parametrize(
    "name",
    ["georef_missing_grid.xodr", "signal_empty_attributes.xodr", "spiral_parampoly3.xodr",
     "elevation_superelevation.xodr", "lane_types.xodr", "left_hand_traffic.xodr"],
)  # fmt: skip
def test_accepted_file_yields_a_net_and_a_world(name):
    net_path = import_opendrive(XODR / name)
    net = load_net(net_path)
    assert len(_driving_lanes(net)) >= 2  # lane_types.xodr adds a parking lane
    assert build_world(net_path).mesh.num_triangles > 0


def test_conversion_is_cached_by_content():
    first = import_opendrive(XODR / "lane_types.xodr")
    mtime = first.stat().st_mtime_ns
    assert import_opendrive(XODR / "lane_types.xodr") == first
    assert first.stat().st_mtime_ns == mtime


def test_sidewalk_lanes_are_kept_for_pedestrians():
    net = _convert("spiral_parampoly3.xodr")
    walk = [lane for e in _edges(net) for lane in e.getLanes() if lane.getPermissions() == {"pedestrian"}]
    assert len(walk) == 2
    assert all(abs(lane.getWidth() - 2.0) < 0.05 for lane in walk)


def test_curves_are_imported_with_fine_resolution():
    net = _convert("spiral_parampoly3.xodr")
    shape = max((lane.getShape() for lane in _driving_lanes(net)), key=len)
    assert len(shape) > 40  # 100 m of road at 1 m resolution, curved over 60 m


def test_elevation_is_kept():
    net = _convert("elevation_superelevation.xodr")
    zs = [z for lane in _driving_lanes(net) for _, _, z in lane.getShape3D()]
    assert min(zs) > 1.5
    assert max(zs) > 4.5


def test_lane_types_keep_their_uses():
    net = _convert("lane_types.xodr")
    perms = [frozenset(lane.getPermissions()) for e in _edges(net) for lane in e.getLanes()]
    assert frozenset({"pedestrian"}) in perms
    assert frozenset({"bicycle"}) in perms
    assert frozenset() in perms  # shoulder, border, median: paved, used by nobody
    assert len(perms) >= 10


def test_left_hand_traffic_is_detected():
    text = import_opendrive(XODR / "left_hand_traffic.xodr").read_text()
    assert 'lefthand="true"' in text


def test_rejected_file_raises_one_line_naming_the_file_and_reason():
    with pytest.raises(NetconvertError) as info:
        import_opendrive(XODR / "rejected_broken.xodr")
    message = str(info.value)
    assert "\n" not in message
    assert str(XODR / "rejected_broken.xodr") in message
    assert "netconvert rejected the file" in message
    assert "end of input" in message


def test_missing_file_is_a_network_error(tmp_path):
    with pytest.raises(Exception, match="not found"):
        import_opendrive(tmp_path / "nope.xodr")


def test_left_hand_geometry_without_a_rule_is_read_as_left_hand_traffic():
    """netconvert's own export of a left-hand network has no rule="LHT": read as right-hand
    traffic, its sidewalks lie on the driving lanes. It is read as left-hand, and said so."""
    net_path = import_opendrive(XODR / "left_hand_no_rule.xodr")
    assert sidewalks_on_driving_lanes(net_path) < 0.01
    assert "read as left-hand traffic" in conversion_notice(net_path)
    assert conversion_notice(import_opendrive(XODR / "lane_types.xodr")) == ""


def test_motorways_are_closed_to_bicycles_and_pedestrians(tmp_path):
    """netconvert opens an OpenDRIVE driving lane to every class; on a road of type motorway
    bicycles (and mopeds, pedestrians) are kept off: no bicycle slows the ego on a motorway."""
    town = _convert("lane_types.xodr")
    assert any(lane.allows("bicycle") for lane in _driving_lanes(town))
    motorway = tmp_path / "motorway.xodr"
    motorway.write_text((XODR / "lane_types.xodr").read_text().replace('type="town"', 'type="motorway"'))
    lanes = _driving_lanes(load_net(import_opendrive(motorway)))
    assert len(lanes) >= 2
    assert not any(lane.allows(c) for lane in lanes for c in ("bicycle", "moped", "pedestrian"))


def test_a_parking_lane_is_its_own_class_on_top_of_its_neighbours_seam():
    import numpy as np
    import shapely

    from networks.classes import SemanticClass
    from networks.world import lane_footprint, lane_types

    net_path = import_opendrive(XODR / "lane_types.xodr")
    net, types = load_net(net_path), lane_types(net_path)
    parking = [lane for e in _edges(net) for lane in e.getLanes() if types.get(lane.getID()) == "parking"]
    assert parking
    mesh = build_world(net_path, props=False, markings=False, traffic_lights=False, signs=False).mesh
    tri = mesh.vertices_m[mesh.triangles].astype(np.float64)
    centroid = tri.mean(axis=1)
    footprint = shapely.union_all([lane_footprint(lane) for lane in parking])
    park = mesh.triangle_class == SemanticClass.PARKING
    assert park.any()
    inside = shapely.contains_xy(footprint.buffer(0.11), centroid[:, 0], centroid[:, 1])
    assert inside[park].all()  # on the parking lanes (and the strips' 5 cm overlap)
    # Seen from above, the whole lane and the seam's band where its strip and the driving lane's
    # overlap are parking (no coplanar tie between the two classes).
    from sensors.o3d import RaycastingScene, o3c

    scene = RaycastingScene()
    scene.add_triangles(o3c.Tensor(mesh.vertices_m), o3c.Tensor(mesh.triangles.astype(np.uint32)))
    band = footprint.buffer(0.04)
    xmin, ymin, xmax, ymax = band.bounds
    gx, gy = np.meshgrid(np.arange(xmin, xmax, 0.02), np.arange(ymin, ymax, 0.02))
    keep = shapely.contains_xy(band, gx, gy)
    rays = np.zeros((int(keep.sum()), 6), np.float32)
    rays[:, 0], rays[:, 1], rays[:, 2], rays[:, 5] = gx[keep], gy[keep], 50.0, -1.0
    hit = scene.cast_rays(o3c.Tensor(rays))["primitive_ids"].numpy()
    seen = mesh.triangle_class[hit[hit != RaycastingScene.INVALID_ID]]
    assert SemanticClass.ROAD not in set(seen.tolist()) and np.mean(seen == SemanticClass.PARKING) > 0.9
