"""The HD map of a network: vector elements and the lane graph, from the same geometry the world
mesh is built from (a dashed divider in the map is where its dashes are in the LiDAR), and the
per-frame view of it around the ego: elements clipped to a bird's-eye range, and rasters.

Elements (map frame, 2D polylines; ids stable for the network):

- ``lane_divider``: every painted lane line between lanes (of one direction or of both), one
  element per single line (a double line is two), ``pattern`` solid / broken / botts dots,
  ``colour`` white / yellow;
- ``edge_line``: painted lines along the road's edge;
- ``stop_line`` (``pattern`` solid) and give-way lines (``stop_line`` with pattern broken);
- ``road_boundary``: the edges of the drivable surface (kerbs, where the road ends);
- ``crossing``: each pedestrian crossing's outline (closed);
- ``lane_centre``: each lane's centre line (junction connectors included), with its lane id.

The lane graph (``lanes``): per SUMO lane its edge, centre line, width, speed, allowed classes,
successors and predecessors (through junctions), left and right neighbours. Also the polygons of
the drivable area, the walkways (sidewalks and walking areas), the crossings and the junctions
(each junction's area as polygons with holes: SUMO's outline of a junction may cross itself).
"""

from __future__ import annotations

from dataclasses import dataclass, fields
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import numpy.typing as npt
import shapely
import sumolib
from shapely.geometry import LineString, Polygon

from networks.geometry import SE3
from networks.markings import PaintedLine, crossing_lanes, painted_lines, read_road_marks
from networks.vocabulary import LineRole

MAP_VERSION = "2"  # part of the cache key of a network's map.json
ELEMENT_TYPES = ("lane_divider", "edge_line", "stop_line", "road_boundary", "crossing", "lane_centre")
RASTER_LAYERS = ("drivable", "lane_divider", "road_boundary", "crossing", "walkway", "car", "truck", "bus",
                 "motorcycle", "bicycle", "pedestrian", "trailer", "construction_vehicle", "traffic_cone",
                 "barrier")  # fmt: skip
ROLE_TYPE = {
    LineRole.DIVIDER: "lane_divider",
    LineRole.EDGE: "edge_line",
    LineRole.STOP: "stop_line",
    LineRole.GIVE_WAY: "stop_line",
}


@dataclass(frozen=True, slots=True)
class MapElement:
    element_id: int
    kind: str  # one of ELEMENT_TYPES
    points_m: npt.NDArray[np.float64]  # (K, 2) map frame; a crossing's outline is closed (first = last)
    pattern: str = ""  # solid, broken, botts dots (painted lines)
    colour: str = ""  # white, yellow (painted lines)
    lane: str = ""  # the SUMO lane it belongs to (painted lines, stop lines, centre lines, crossings)


@dataclass(frozen=True, slots=True)
class LaneRecord:
    lane_id: str
    edge_id: str
    centre_m: list[list[float]]  # (K, 3) map frame
    width_m: float
    speed_mps: float
    allow: list[str]
    successors: list[str]
    predecessors: list[str]
    left: str  # the neighbour lane on the left in the same direction ('' if none)
    right: str
    junction: str  # the junction a connector lane crosses ('' for a road's lane)


class HdMap:
    """The network's map: its elements with an index for range queries, the lane graph, and
    the areas the rasters are drawn from."""

    def __init__(self, net: sumolib.net.Net, lines: list[PaintedLine], left_hand: bool) -> None:
        elements: list[MapElement] = []

        def add(kind: str, points: npt.ArrayLike, **attrs: str) -> None:
            p = np.asarray(points, np.float64)[:, :2]
            if p.shape[0] >= 2:
                elements.append(MapElement(len(elements), kind, p, **attrs))

        for line in lines:
            add(ROLE_TYPE[line.role], line.polyline_m, pattern=line.pattern,
                colour="yellow" if line.yellow else "white", lane=line.lane_id)  # fmt: skip
        drivable, walkways, junctions = _areas(net)
        for ring in _rings(drivable):
            add("road_boundary", ring)
        self.crossings: list[Polygon] = []
        for lane in crossing_lanes(net):
            outline = LineString(np.asarray(lane.getShape())[:, :2]).buffer(
                lane.getWidth() / 2.0, cap_style="flat", join_style="mitre"
            )  # mitred like the zebra stripes painted along it
            if not outline.is_empty:
                self.crossings.append(outline)
                for ring in _rings(outline, holes=False):
                    add("crossing", ring, lane=lane.getID())
        self.lanes = _lane_graph(net, left_hand)
        for record in self.lanes:
            add("lane_centre", np.asarray(record.centre_m), lane=record.lane_id)
        self.elements = elements
        self.drivable = drivable
        self.walkways = walkways
        self.junctions = junctions
        self._lines = [LineString(e.points_m) for e in elements]
        self._tree = shapely.STRtree(self._lines)
        self._lane_polygons = {
            r.lane_id: LineString(np.asarray(r.centre_m)[:, :2]).buffer(r.width_m / 2.0, cap_style="flat")
            for r in self.lanes
            if len(r.centre_m) >= 2
        }
        crossings = shapely.union_all(self.crossings) if self.crossings else Polygon()
        self._areas = {"drivable": drivable, "crossing": crossings, "walkway": walkways}

    def lane_polygon(self, lane_id: str) -> Polygon | None:
        return self._lane_polygons.get(lane_id)

    def static_json(self) -> dict[str, Any]:
        """The whole map in the map frame (``map/map.json``)."""
        return {
            "elements": [element_json(e, e.points_m) for e in self.elements],
            "lanes": [{f.name: getattr(r, f.name) for f in fields(r)} for r in self.lanes],
            "junctions": [{"id": jid, "polygons": polygons_json(area)} for jid, area in self.junctions],
        }

    def view(
        self, map_SE3_ego: SE3, half_x_m: float, half_y_m: float
    ) -> list[tuple[MapElement, npt.NDArray[np.float64]]]:
        """The elements within the range ``|x| <= half_x_m``, ``|y| <= half_y_m`` of the ego,
        each with its ``(K, 2)`` points in the ego frame, clipped to the range (an element the
        range cuts in two gives two pieces)."""
        hits = self._tree.query(_range_in_map(map_SE3_ego, half_x_m, half_y_m), predicate="intersects")
        ego_SE3_map = map_SE3_ego.inverse()
        r, t = ego_SE3_map.rotation[:2, :2], ego_SE3_map.translation[:2]
        out = []
        for k in sorted(int(i) for i in hits):
            element = self.elements[k]
            local = element.points_m @ r.T + t
            if element.kind == "crossing" and local.shape[0] >= 4:  # an outline stays closed when clipped
                area = shapely.clip_by_rect(Polygon(local), -half_x_m, -half_y_m, half_x_m, half_y_m)
                for part in shapely.get_parts(area):
                    if isinstance(part, Polygon) and not part.is_empty and part.area > 0:
                        out.append((element, np.asarray(part.exterior.coords)[:, :2]))
                continue
            clipped = shapely.clip_by_rect(LineString(local), -half_x_m, -half_y_m, half_x_m, half_y_m)
            for piece in shapely.get_parts(
                shapely.line_merge(clipped) if clipped.geom_type == "MultiLineString" else clipped
            ):
                coords = np.asarray(piece.coords)[:, :2] if not piece.is_empty else np.zeros((0, 2))
                if coords.shape[0] >= 2:
                    out.append((element, coords))
        return out

    def raster(self, map_SE3_ego: SE3, half_x_m: float, half_y_m: float, resolution_m: float,
               view: list[tuple[MapElement, npt.NDArray[np.float64]]]) -> npt.NDArray[np.uint8]:  # fmt: skip
        """``(L, H, W) uint8`` layers (:data:`RASTER_LAYERS` without the object layers) of the
        range: rows from +x (ahead) down, columns from +y (left) rightwards; pixel (r, c)
        covers x in ``half_x - (r + 1) * res .. half_x - r * res`` and likewise y."""
        h, w = round(2 * half_x_m / resolution_m), round(2 * half_y_m / resolution_m)
        layers = np.zeros((len(RASTER_LAYERS), h, w), np.uint8)
        reach = _range_in_map(map_SE3_ego, half_x_m, half_y_m).buffer(resolution_m)
        # Area layers: a pixel is set when its centre lies in the area (exact at edges, unlike a
        # polygon fill, which also sets the pixels an edge passes through).
        rows, cols = np.mgrid[0:h, 0:w]
        centres = np.column_stack(
            [half_x_m - (rows.ravel() + 0.5) * resolution_m, half_y_m - (cols.ravel() + 0.5) * resolution_m]
        )
        centres_map = centres @ map_SE3_ego.rotation[:2, :2].T + map_SE3_ego.translation[:2]
        for name in ("drivable", "crossing", "walkway"):
            area = self._areas[name].intersection(reach)
            if not area.is_empty:
                inside = shapely.contains_xy(area, centres_map[:, 0], centres_map[:, 1])
                layers[RASTER_LAYERS.index(name)] = inside.reshape(h, w)
        for element, local in view:
            if element.kind not in ("lane_divider", "road_boundary"):
                continue
            pts = raster_px(local, half_x_m, half_y_m, resolution_m)
            cv2.polylines(layers[RASTER_LAYERS.index(element.kind)], [pts], False, 1, 1, cv2.LINE_8, 3)
        return layers


def _range_in_map(map_SE3_ego: SE3, half_x_m: float, half_y_m: float) -> Polygon:
    """The rectangle ``|x| <= half_x_m``, ``|y| <= half_y_m`` of the ego frame, in the map frame."""
    corners = np.array([[half_x_m, half_y_m], [half_x_m, -half_y_m], [-half_x_m, -half_y_m], [-half_x_m, half_y_m]])
    return Polygon(map_SE3_ego.transform_from(np.column_stack([corners, np.zeros(4)]))[:, :2])


def raster_px(
    xy_ego_m: npt.NDArray[np.float64], half_x_m: float, half_y_m: float, resolution_m: float
) -> npt.NDArray[np.int32]:
    """Ego-frame points as raster (column, row) coordinates with 3 fractional bits, as OpenCV's
    drawing functions take them with ``shift=3`` (row 0 ahead, column 0 on the left)."""
    col = (half_y_m - xy_ego_m[:, 1]) / resolution_m - 0.5
    row = (half_x_m - xy_ego_m[:, 0]) / resolution_m - 0.5
    return np.round(np.column_stack([col, row]) * 8).astype(np.int32)


def _round(points: npt.NDArray[np.float64]) -> list[list[float]]:
    return np.round(points, 3).tolist()  # type: ignore[no-any-return]


def element_json(element: MapElement, points: npt.NDArray[np.float64]) -> dict[str, Any]:
    """An element as JSON: id, type, points (rounded to mm) and its attributes."""
    out: dict[str, Any] = {"id": element.element_id, "type": element.kind, "points": _round(points)}
    for key in ("pattern", "colour", "lane"):
        value = getattr(element, key)
        if value:
            out[key] = value
    return out


def _polygons(area: shapely.Geometry) -> list[Polygon]:
    """The polygons of an area of any shape (a polygon, with holes or not, several, a collection)."""
    return [part for part in shapely.get_parts(area) if part.geom_type == "Polygon" and not part.is_empty]


def _rings(area: shapely.Geometry, holes: bool = True) -> list[npt.NDArray[np.float64]]:
    """The exterior rings of every polygon of ``area``, and their interior rings (``holes``)."""
    out = []
    for part in _polygons(area):
        out.append(np.asarray(part.exterior.coords))
        out += [np.asarray(ring.coords) for ring in part.interiors] if holes else []
    return out


def polygons_json(area: shapely.Geometry) -> list[list[list[list[float]]]]:
    """An area as the coordinates of a GeoJSON MultiPolygon: per polygon, its outline, then its
    holes (closed rings of x, y, rounded to mm)."""
    return [
        [_round(np.asarray(part.exterior.coords)), *(_round(np.asarray(r.coords)) for r in part.interiors)]
        for part in _polygons(area)
    ]


def _areas(net: sumolib.net.Net) -> tuple[shapely.Geometry, shapely.Geometry, list[tuple[str, shapely.Geometry]]]:
    """The drivable area (lanes open to vehicles, parking lanes, crossings and junctions), the walkways
    (sidewalks and walking areas) and the junctions' areas (an outline SUMO draws crossing
    itself makes several polygons, or one with holes, as in the world mesh)."""
    drive, driven, sidewalks, corners = [], [], [], []
    for edge in net.getEdges(withInternal=True):
        function = edge.getFunction()
        for lane in edge.getLanes():
            shape = np.asarray(lane.getShape())
            if shape.shape[0] < 2:
                continue
            if function == "crossing":  # paved at the road's level; its ends past the junction count too
                drive.append(LineString(shape[:, :2]).buffer(lane.getWidth() / 2.0, cap_style="flat"))
                continue
            if function == "walkingarea":
                corners.append(Polygon(shape[:, :2]).buffer(0))
                continue
            strip = LineString(shape[:, :2]).buffer(lane.getWidth() / 2.0, cap_style="flat")
            if lane.getPermissions() == {"pedestrian"}:
                sidewalks.append(strip)
                continue
            drive.append(strip)
            if lane.getPermissions():  # open to some vehicle (parking lanes are open to none)
                driven.append(strip)
    junctions = []
    for node in net.getNodes():
        outline = np.asarray(node.getShape())
        if len(outline) >= 3:
            junctions.append((node.getID(), Polygon(outline[:, :2]).buffer(0)))
    # As in the world mesh: a walking area is raised as sidewalk where no vehicle lane runs over
    # it (a junction's corners); the junction's outline covers it, the drivable area does not.
    raised = shapely.union_all(corners).difference(shapely.union_all(driven)) if corners else Polygon()
    walkways = shapely.union_all([*sidewalks, raised]) if sidewalks or corners else Polygon()
    paved = shapely.union_all(drive + [j for _, j in junctions]).buffer(0.05).buffer(-0.05)  # seams closed
    drivable = paved.difference(walkways)
    return drivable, walkways, junctions


def _lane_graph(net: sumolib.net.Net, left_hand: bool) -> list[LaneRecord]:
    out = []
    for edge in sorted(net.getEdges(withInternal=True), key=lambda e: e.getID()):
        function = edge.getFunction()
        if function not in ("", "internal"):
            continue
        lanes = sorted(edge.getLanes(), key=lambda lane: lane.getIndex())
        for lane in lanes:
            if not lane.getPermissions() - {"pedestrian"} or len(lane.getShape()) < 2:
                continue
            i = lane.getIndex()
            succ = sorted({(c.getViaLaneID() or c.getToLane().getID()) for c in lane.getOutgoing() if c.getToLane()})
            pred = sorted({x.getID() for x in lane.getIncoming(onlyDirect=True)})
            inner = lanes[i + 1].getID() if i + 1 < len(lanes) else ""  # SUMO counts lanes from the road's edge
            outer = lanes[i - 1].getID() if i > 0 else ""
            out.append(LaneRecord(
                lane.getID(), edge.getID(), _round(np.asarray(lane.getShape3D(), np.float64)), float(lane.getWidth()),
                float(lane.getSpeed()), sorted(lane.getPermissions()), succ, pred,
                outer if left_hand else inner, inner if left_hand else outer,
                edge.getFromNode().getID() if function == "internal" else "",
            ))  # fmt: skip
    return out


def build_map(net: sumolib.net.Net, xodr_path: Path | None, left_hand: bool) -> HdMap:
    """The map of a network converted from ``xodr_path`` (its roadMarks, as the world's paint)."""
    return HdMap(net, painted_lines(net, read_road_marks(xodr_path), left_hand), left_hand)
