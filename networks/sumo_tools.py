"""Locate the SUMO installation that the ``eclipse-sumo`` wheel ships.

``SUMO_HOME`` is taken from the ``sumo`` Python package and exported, so that
libsumo, netconvert and SUMO's Python tools agree on one installation.
"""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

from networks.errors import ToolNotFoundError


def sumo_home() -> Path:
    try:
        import sumo
    except ImportError as err:
        msg = "the eclipse-sumo package is not installed (run `make venv`)"
        raise ToolNotFoundError(msg) from err
    home = Path(sumo.SUMO_HOME)
    os.environ["SUMO_HOME"] = str(home)
    return home


def sumo_binary(name: str) -> Path:
    """Path of a SUMO executable such as ``netconvert`` or ``sumo``."""
    path = sumo_home() / "bin" / name
    if not path.exists():
        raise ToolNotFoundError(f"{path}: SUMO tool {name!r} not found in the installation")
    return path


def sumo_tool(relative: str) -> Path:
    """Path of a script under ``$SUMO_HOME/tools`` such as ``randomTrips.py``."""
    path = sumo_home() / "tools" / relative
    if not path.exists():
        raise ToolNotFoundError(f"{path}: SUMO tool script {relative!r} not found in the installation")
    return path


def sumo_refusal(args: list[str]) -> str:
    """Run the ``sumo`` binary with ``args`` (a network and what else a simulation loads) up to
    its first step; return '' if it loads them, else SUMO's own first error message."""
    quiet = [(o, v) for o, v in (("--end", "0"), ("--no-step-log", "true"), ("--no-warnings", "true")) if o not in args]
    cmd = [str(sumo_binary("sumo")), *args, *(word for pair in quiet for word in pair)]
    proc = subprocess.run(cmd, capture_output=True, text=True, check=False)
    if proc.returncode == 0:
        return ""
    lines = [ln.strip() for ln in proc.stderr.splitlines() if ln.strip()]
    errors = [ln.removeprefix("Error: ") for ln in lines if ln.startswith("Error: ")]
    return (errors or lines or [f"exit code {proc.returncode}"])[0]
