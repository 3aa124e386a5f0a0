"""OpenDRIVE -> SUMO network through netconvert, cached by content and options."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

from networks.cache import cache_dir, digest
from networks.errors import NetconvertError, NetworkError
from networks.sumo_tools import sumo_binary

CONVERT_VERSION = "1"

# Sidewalks and crossings for pedestrians, smooth lane shapes, z kept from the file.
IMPORT_OPTIONS: tuple[str, ...] = (
    "--opendrive.import-all-lanes", "true",
    "--opendrive.curve-resolution", "1.0",
    "--sidewalks.guess", "true",
    "--crossings.guess", "true",
    "--junctions.corner-detail", "8",
    "--geometry.avoid-overlap", "true",
    "--no-warnings", "true",
)  # fmt: skip

_GEO_REFERENCE = re.compile(r"<geoReference>.*?</geoReference>|<geoReference\s*/>", re.DOTALL)


def import_opendrive(xodr_path: Path) -> Path:
    """Return the SUMO ``.net.xml`` for an OpenDRIVE file, converting it on first use."""
    if not xodr_path.is_file():
        raise NetworkError(f"{xodr_path}: OpenDRIVE file not found")
    data = xodr_path.read_bytes()
    key = digest(CONVERT_VERSION, data, *IMPORT_OPTIONS)
    folder = cache_dir("nets", f"{xodr_path.stem}-{key}")
    net = folder / "net.net.xml"
    if net.exists():
        return net
    partial = folder / "net.partial.xml"
    error = _run_netconvert(xodr_path, partial)
    if error and _GEO_REFERENCE.search(data.decode("utf-8", "replace")):
        # Projection data often names datum grids that are not installed: retry without it.
        stripped = folder / "no-georef.xodr"
        stripped.write_text(_GEO_REFERENCE.sub("", data.decode("utf-8", "replace")))
        error = _run_netconvert(stripped, partial)
    if error:
        raise NetconvertError(f"{xodr_path}: netconvert rejected the file: {error}")
    partial.replace(net)
    return net


def _run_netconvert(xodr_path: Path, out_path: Path) -> str:
    """Run netconvert; return '' on success, else the tail of its error output."""
    cmd = [str(sumo_binary("netconvert")), "--opendrive-files", str(xodr_path), *IMPORT_OPTIONS, "-o", str(out_path)]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if proc.returncode == 0 and out_path.exists() and out_path.stat().st_size > 0:
        return ""
    lines = [ln for ln in proc.stderr.strip().splitlines() if ln.startswith("Error")] or proc.stderr.splitlines()
    return " | ".join(lines[-2:]).strip() or f"exit code {proc.returncode}"
