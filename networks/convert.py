"""OpenDRIVE -> SUMO network through netconvert, cached by content and options."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path
from xml.etree import ElementTree

import shapely

from networks.cache import cache_dir, digest, intact, place, scratch_dir
from networks.errors import NetconvertError, NetworkError, SumoRefusedError
from networks.opendrive import opendrive_root
from networks.sumo_tools import sumo_binary, sumo_refusal
from networks.world import lane_footprint, load_net

CONVERT_VERSION = "8"

# Sidewalks and crossings for pedestrians, smooth lane shapes, z kept from the file.
IMPORT_OPTIONS: tuple[str, ...] = (
    "--opendrive.curve-resolution", "1.0",
    "--sidewalks.guess", "true",
    "--crossings.guess", "true",
    "--junctions.corner-detail", "8",
    "--geometry.avoid-overlap", "true",
    "--no-turnarounds.except-deadend", "true",
    "--ignore-errors.edge-type", "true",
    "--no-warnings", "true",
    "--output.original-names", "true",  # each lane's OpenDRIVE road and lane (origId): its roadMarks
)  # fmt: skip

_VEHICLES_ONLY = (
    'disallow="pedestrian rail rail_urban rail_electric rail_fast tram drone aircraft scooter '
    'container wheelchair subway cable_car ship"'
)
_RAMP = 'disallow="pedestrian bicycle moped rail rail_urban rail_electric rail_fast tram drone aircraft scooter ship"'

# OpenDRIVE lane type -> SUMO lane. Unlike netconvert's default map, sidewalks allow
# pedestrians and biking lanes bicycles, and shoulders, borders and medians stay as
# lanes nobody drives on, so that every paved surface reaches the world mesh.
LANE_TYPES_XML = "\n".join(
    [
        "<types>",
        *(
            f'  <type id="{t}" priority="1" speed="13.89" width="3.65" {_VEHICLES_ONLY}/>'
            for t in ("driving", "stop", "entry", "exit", "bidirectional", "mwyEntry", "mwyExit")
        ),
        *(f'  <type id="{t}" priority="1" speed="22.22" width="3.65" {_RAMP}/>' for t in ("onRamp", "offRamp")),
        '  <type id="parking" priority="0" speed="1.39" width="2.50" disallow="all"/>',
        '  <type id="sidewalk" priority="-2" speed="2.78" width="2.50" allow="pedestrian"/>',
        '  <type id="walking" priority="-2" speed="2.78" width="2.50" allow="pedestrian"/>',
        '  <type id="biking" priority="-1" speed="5.56" width="1.50" allow="bicycle"/>',
        *(
            f'  <type id="{t}" priority="0" speed="1.39" width="0.5" disallow="all"/>'
            for t in ("shoulder", "border", "median", "curb", "restricted")
        ),
        '  <type id="none" priority="0" speed="1.39" width="1.0" disallow="all" discard="true"/>',
        '  <type id="tram" priority="2" speed="13.89" width="3.65" allow="tram"/>',
        '  <type id="rail" priority="3" speed="33.33" width="3.65" allow="rail rail_urban rail_electric rail_fast"/>',
        "</types>",
        "",
    ]
)

NOTICE_FILE = "notice.txt"
MISREAD_SIDEWALK_SHARE = 0.5  # of the sidewalk area on driving lanes: the file is left-hand traffic
SIDEWALK_MAX_SPEED_MPS = 13.89  # netconvert's default for --sidewalks.guess.max-speed

_SIGNAL_TAG = re.compile(r"<signal(?:Reference)?\s[^>]*>")
_SIGNAL_DEFAULTS = {"orientation": "none", "dynamic": "no", "zOffset": "0", "country": "OpenDRIVE", "type": "-1",
                    "subtype": "-1", "value": "0", "height": "0", "width": "0", "hOffset": "0", "pitch": "0",
                    "roll": "0"}  # fmt: skip
_GEO_REFERENCE = re.compile(r"<geoReference>.*?</geoReference>|<geoReference\s*/>", re.DOTALL)


def import_opendrive(xodr_path: Path) -> Path:
    """Return the SUMO ``.net.xml`` for an OpenDRIVE file, converting it on first use.

    A file netconvert rejects is retried with its signals' empty attributes repaired,
    then also without its geoReference (proj strings often name datum grids that are not
    installed); if all fail, the error names the file and netconvert's first reason.
    """
    if not xodr_path.is_file():
        raise NetworkError(f"{xodr_path}: OpenDRIVE file not found")
    data = xodr_path.read_bytes()
    key = digest(CONVERT_VERSION, data, LANE_TYPES_XML, *IMPORT_OPTIONS)
    folder = cache_dir("nets", f"{xodr_path.stem}-{key}")
    net = folder / "net.net.xml"
    if intact(net):
        return net
    with scratch_dir(folder) as scratch:
        types = scratch / "lanes.typ.xml"
        types.write_text(LANE_TYPES_XML)
        partial = scratch / "net.partial.xml"
        source = xodr_path  # the file as converted: the user's, or a repaired copy
        first_error = error = _run_netconvert(source, types, partial)
        text = data.decode("utf-8", "replace")
        for name, repair in (("signals.xodr", _repair_signals), ("no-georef.xodr", _strip_geo_reference)):
            if not error:
                break
            repaired = repair(text)
            if repaired == text:
                continue
            text, source = repaired, scratch / name
            source.write_text(text)
            error = _run_netconvert(source, types, partial)
        if error:
            (scratch / "netconvert.log").replace(folder / "netconvert.log")
            raise NetconvertError(f"{xodr_path}: netconvert rejected the file: {first_error}")
        if not road_facts(source)[1] and sidewalks_on_driving_lanes(partial) > MISREAD_SIDEWALK_SHARE:
            # Left-hand geometry read as right-hand traffic puts every sidewalk on a lane.
            mirrored = scratch / "net.lefthand.xml"
            if not _run_netconvert(source, types, mirrored, left_hand=True) and (
                sidewalks_on_driving_lanes(mirrored) < MISREAD_SIDEWALK_SHARE / 5
            ):
                mirrored.replace(partial)
                (folder / NOTICE_FILE).write_text(
                    f'note: {xodr_path}: read as left-hand traffic (its roads do not say rule="LHT", '
                    "but read as right-hand traffic its sidewalks lay on the driving lanes)"
                )
        (scratch / "netconvert.log").replace(folder / "netconvert.log")
        _drop_header_comment(partial)
        _keep_off_motorways(partial, motorway_roads(source))
        refusal = sumo_refusal(["-n", str(partial)])
        if refusal:
            refused = folder / "net.refused.xml"
            partial.replace(refused)
            raise SumoRefusedError(
                f"{xodr_path}: SUMO does not load the network converted from it ({refused}): {refusal}"
            )
        place(partial, net)
    return net


def _drop_header_comment(net_path: Path) -> None:
    """Remove netconvert's header comment (its options, with this run's scratch paths), so the
    file, and every cache key made from it, depends on the network only."""
    text = net_path.read_text(encoding="utf-8")
    net_path.write_text(re.sub(r"<!--.*?-->\s*", "", text, count=1, flags=re.DOTALL), encoding="utf-8")


MOTORWAY_BANNED = ("bicycle", "moped", "pedestrian")  # off roads of OpenDRIVE type "motorway"


def motorway_roads(xodr_path: Path) -> set[str]:
    """Ids of the OpenDRIVE roads with a ``<type type="motorway">`` record."""
    try:
        roads = opendrive_root(xodr_path).iter("road")
    except ElementTree.ParseError:
        return set()
    return {road.get("id", "") for road in roads if _is_motorway(road)}


def _is_motorway(road: ElementTree.Element) -> bool:
    return any(t.get("type") == "motorway" for t in road.iter("type"))


def _keep_off_motorways(net_path: Path, roads: set[str]) -> None:
    """Close the lanes of motorway roads that cars may use to bicycles, mopeds and pedestrians
    (netconvert gives an OpenDRIVE driving lane to every vehicle class, whatever its road's
    type); lanes are found by the road in their ``origId``. Lanes closed to cars (sidewalks,
    bicycle lanes, shoulders) keep their permissions: no lane ends up open to nobody by this
    edit, and every lane, edge and connection stays as netconvert wrote it."""
    if not roads:
        return
    tree = ElementTree.parse(net_path)
    changed = False
    for lane in tree.getroot().iter("lane"):
        origin = next((p.get("value", "") for p in lane.iter("param") if p.get("key") == "origId"), "")
        if not any(part.rsplit("_", 1)[0] in roads for part in origin.split()):
            continue
        allowed = _lane_classes(lane.attrib)
        if "passenger" not in allowed or not allowed & set(MOTORWAY_BANNED):
            continue
        if "allow" in lane.attrib and "all" not in lane.attrib["allow"].split():
            lane.set("allow", " ".join(c for c in lane.attrib["allow"].split() if c not in MOTORWAY_BANNED))
        else:
            lane.attrib.pop("allow", None)
            banned = lane.get("disallow", "").split()
            lane.set("disallow", " ".join([*banned, *(c for c in MOTORWAY_BANNED if c not in banned)]))
        changed = True
    if changed:
        tree.write(net_path, encoding="UTF-8", xml_declaration=True)


def _lane_classes(attrib: dict[str, str]) -> set[str]:
    """The vehicle classes a ``<lane>`` of a SUMO network admits, of the ones this module edits."""
    if "allow" in attrib:
        allowed = set(attrib["allow"].split())
        return {"passenger", *MOTORWAY_BANNED} if "all" in allowed else allowed
    disallowed = set(attrib.get("disallow", "").split())
    return set() if "all" in disallowed else {"passenger", *MOTORWAY_BANNED} - disallowed


def conversion_notice(net_path: Path) -> str:
    """What the user should know about how :func:`import_opendrive` read the file ('' if nothing)."""
    notice = net_path.with_name(NOTICE_FILE)
    return notice.read_text() if notice.exists() else ""


def sidewalks_on_driving_lanes(net_path: Path) -> float:
    """Share of the pedestrian-only lanes' area that lies on lanes open to cars (0 if none)."""
    walk, drive = [], []
    for edge in load_net(net_path).getEdges(withInternal=False):
        for lane in edge.getLanes():
            if edge.getFunction() or len(lane.getShape()) < 2:
                continue
            if lane.getPermissions() == {"pedestrian"}:
                walk.append(lane_footprint(lane))
            elif lane.allows("passenger"):
                drive.append(lane_footprint(lane))
    if not walk or not drive:
        return 0.0
    sidewalks = shapely.union_all(walk)
    return float(sidewalks.intersection(shapely.union_all(drive)).area / max(sidewalks.area, 1e-9))


def _strip_geo_reference(text: str) -> str:
    return _GEO_REFERENCE.sub("", text)


def _repair_signals(text: str) -> str:
    """Drop signals without an id and give empty signal attributes netconvert's defaults."""

    def fix(match: re.Match[str]) -> str:
        tag = match.group(0)
        if re.search(r'\sid=""', tag):
            return "" if tag.endswith("/>") else "<!-- dropped signal -->"
        for attr, default in _SIGNAL_DEFAULTS.items():
            tag = re.sub(rf'(\s{attr})=""', rf'\1="{default}"', tag)
        return re.sub(r'\s[A-Za-z]+=""', "", tag)

    return _SIGNAL_TAG.sub(fix, text)


def _run_netconvert(xodr_path: Path, types_path: Path, out_path: Path, left_hand: bool = False) -> str:
    """Run netconvert (as left-hand traffic if the file says so, or ``left_hand``), guessing no
    sidewalks on the roads :func:`road_facts` names; return '' on success, else its reason on
    one line. A road netconvert splits into several edges (at lane sections and speed changes:
    ``1#0``, ``1#1``) is converted again with those edges' ids."""
    bare, says_left_hand = road_facts(xodr_path)
    exclude = [edge for road in bare for edge in (road, "-" + road)]
    error = _netconvert(xodr_path, types_path, out_path, left_hand or says_left_hand, exclude)
    if not error and bare:
        edges = edges_of_roads(out_path, set(bare))
        if not edges <= set(exclude):
            error = _netconvert(
                xodr_path, types_path, out_path, left_hand or says_left_hand, sorted(edges | set(exclude))
            )
    return error


def _netconvert(xodr_path: Path, types_path: Path, out_path: Path, left_hand: bool, no_sidewalks: list[str]) -> str:
    cmd = [
        str(sumo_binary("netconvert")), "--opendrive-files", str(xodr_path), "--type-files", str(types_path),
        *IMPORT_OPTIONS, "-o", str(out_path),
    ]  # fmt: skip
    if no_sidewalks:
        cmd += ["--sidewalks.guess.exclude", ",".join(no_sidewalks)]
    if left_hand:
        cmd += ["--lefthand", "true"]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    out_path.with_name("netconvert.log").write_text(proc.stderr)
    if proc.returncode == 0 and out_path.exists() and out_path.stat().st_size > 0:
        return ""
    return netconvert_reason(proc.stderr, proc.returncode)


def edges_of_roads(net_path: Path, roads: set[str]) -> set[str]:
    """Ids of the normal edges of a converted network with a lane of one of the OpenDRIVE
    ``roads`` (by the road in the lane's ``origId``)."""
    out = set()
    for edge in ElementTree.parse(net_path).getroot().iter("edge"):
        if edge.get("function"):
            continue
        origins = (p.get("value", "") for p in edge.iter("param") if p.get("key") == "origId")
        if any(part.rsplit("_", 1)[0] in roads for origin in origins for part in origin.split()):
            out.add(edge.get("id", ""))
    return out


def road_facts(xodr_path: Path) -> tuple[list[str], bool]:
    """Ids of the OpenDRIVE roads that get no guessed sidewalk (motorways, and roads whose
    lanes are all faster than a town street), and whether every road keeps left
    (``rule="LHT"``, which netconvert does not read itself).

    netconvert decides whether to guess a sidewalk from the road type's default speed,
    not from the lanes' own speed records, so motorways would get sidewalks otherwise.
    """
    try:
        roads = list(opendrive_root(xodr_path).iter("road"))
    except ElementTree.ParseError:
        return [], False  # netconvert reports the broken file itself
    bare = []
    for road in roads:
        speeds = [_speed_mps(s) for s in road.iter("speed")]
        fast = bool(speeds) and min(speeds) > SIDEWALK_MAX_SPEED_MPS
        if road.get("junction", "-1") == "-1" and (fast or _is_motorway(road)):
            bare.append(road.get("id", ""))
    left_hand = bool(roads) and all(road.get("rule", "RHT").upper() == "LHT" for road in roads)
    return bare, left_hand


_MPS_PER_UNIT = {"m/s": 1.0, "km/h": 1.0 / 3.6, "mph": 0.44704}


def _speed_mps(record: ElementTree.Element) -> float:
    """A ``<speed max=... unit=...>`` record in m/s (OpenDRIVE's default unit; 0 if unreadable)."""
    return _float(record.get("max")) * _MPS_PER_UNIT.get((record.get("unit") or "m/s").strip(), 1.0)


def _float(text: str | None) -> float:
    try:
        return float(text or 0.0)
    except ValueError:
        return 0.0


def netconvert_reason(stderr: str, returncode: int) -> str:
    """The error lines of netconvert's output joined on one line (without the final 'Quitting')."""
    lines = [ln.strip() for ln in stderr.splitlines() if ln.strip()]
    errors = [ln.removeprefix("Error: ") for ln in lines if ln.startswith("Error")]
    errors = [ln for ln in errors if not ln.startswith("Quitting")] or errors
    reason = "; ".join(dict.fromkeys(errors[-3:])) or (lines[-1] if lines else "")
    return reason or f"exit code {returncode}"
