"""The one place that imports Open3D.

Open3D's wheel links ``libusb-1.0.so.0``; the ``libusb-package`` wheel ships it, and
it is loaded globally here first so that no system package is needed.
"""

from __future__ import annotations

import ctypes
import os
from typing import Any

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")


def _preload_libusb() -> None:
    try:
        import libusb_package
    except ImportError:
        return
    path = libusb_package.get_library_path()
    if path is not None:
        ctypes.CDLL(str(path), mode=ctypes.RTLD_GLOBAL)


_preload_libusb()

import open3d  # noqa: E402

o3d: Any = open3d
o3c: Any = open3d.core
RaycastingScene: Any = open3d.t.geometry.RaycastingScene
INVALID_ID: int = int(open3d.t.geometry.RaycastingScene.INVALID_ID)
