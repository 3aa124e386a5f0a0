"""Pictures of a frame's occupancy for ``summary/``: ``occupancy_<frame>.png`` (a horizontal slice
1 m above the ground, the class of the highest occupied voxel of each column, and what the
LiDAR and the cameras observed) and ``occupancy_3d_<frame>.png`` (the observed occupied voxels
in 3D). Classes in their MCAP colours; +x (ahead) points up in the flat pictures."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import matplotlib
import numpy as np
import numpy.typing as npt

from gtgen.colours import CLASS_RGB
from gtgen.load import load_occupancy
from gtgen.occupancy import FREE_NATIVE
from networks.classes import SemanticClass

matplotlib.use("Agg")
import matplotlib.pyplot as plt
from matplotlib.patches import Patch

SLICE_HEIGHT_M = 1.0
MASK_RGB = {"neither": (0.0, 0.0, 0.0), "LiDAR only": (0.9, 0.7, 0.1), "camera only": (0.2, 0.5, 1.0),
            "both": (1.0, 1.0, 1.0)}  # fmt: skip


def _colour(cls: int) -> tuple[float, float, float]:
    if cls in SemanticClass._value2member_map_:
        return CLASS_RGB.get(SemanticClass(cls), (0.8, 0.8, 0.8))
    return (0.8, 0.8, 0.8)


def _name(cls: int) -> str:
    return SemanticClass(cls).label if cls in SemanticClass._value2member_map_ else str(cls)


def class_image(classes: npt.NDArray[np.uint8]) -> npt.NDArray[np.float64]:
    """``(X, Y)`` classes as an RGB image with +x up and +y left (free: dark grey)."""
    rgb = np.full((*classes.shape, 3), 0.12)
    for cls in np.unique(classes).tolist():
        if cls != FREE_NATIVE:
            rgb[classes == cls] = _colour(int(cls))
    return np.asarray(rgb[::-1, ::-1], np.float64)


def top_classes(semantics: npt.NDArray[np.uint8]) -> npt.NDArray[np.uint8]:
    """``(X, Y)``: the class of the highest occupied voxel of each column (free if none)."""
    occupied = semantics != FREE_NATIVE
    top = semantics.shape[2] - 1 - np.argmax(occupied[:, :, ::-1], axis=2)
    out = np.take_along_axis(semantics, top[:, :, None], axis=2)[:, :, 0]
    return np.where(occupied.any(axis=2), out, FREE_NATIVE).astype(np.uint8)


def occupancy_pictures(run_dir: Path, frame: int, folder: Path) -> None:
    data = load_occupancy(run_dir, frame)
    semantics, lidar, camera = data["semantics_native"], data["mask_lidar"], data["mask_camera"]
    r, voxel = data["range_m"], float(data["voxel_m"])
    layer = int(np.clip((SLICE_HEIGHT_M - r[2]) // voxel, 0, semantics.shape[2] - 1))
    extent = (float(r[4]), float(r[1]), float(r[0]), float(r[3]))  # y left on the left, x ahead up
    seen = np.zeros((*semantics.shape[:2], 3))
    lid, cam = lidar[:, :, layer], camera[:, :, layer]
    for name, mask in (("LiDAR only", lid & ~cam), ("camera only", cam & ~lid), ("both", lid & cam)):
        seen[mask] = MASK_RGB[name]
    fig, axes = plt.subplots(1, 3, figsize=(18, 6.6))
    z0 = r[2] + layer * voxel
    panels: list[tuple[Any, str]] = [
        (class_image(semantics[:, :, layer]), f"classes at z {z0:.1f}..{z0 + voxel:.1f} m"),
        (class_image(top_classes(semantics)), "highest occupied voxel of each column"),
        (seen[::-1, ::-1], f"observed at z {z0:.1f}..{z0 + voxel:.1f} m"),
    ]
    for ax, (image, title) in zip(axes, panels, strict=True):
        ax.imshow(image, extent=extent, interpolation="nearest")
        ax.set_title(title)
        ax.set_xlabel("y (m, left positive)")
        ax.set_ylabel("x (m, ahead)")
    present = [c for c in np.unique(semantics).tolist() if c != FREE_NATIVE]
    axes[1].legend(handles=[Patch(color=_colour(c), label=_name(c)) for c in present], loc="upper right", fontsize=7)
    axes[2].legend(handles=[Patch(color=rgb, label=n) for n, rgb in MASK_RGB.items()], loc="upper right", fontsize=7)
    fig.suptitle(f"occupancy, frame {frame} (ego at the centre, {voxel:g} m voxels)")
    fig.tight_layout()
    fig.savefig(folder / f"occupancy_{frame:06d}.png", dpi=80)
    plt.close(fig)
    occupancy_3d(semantics, lidar | camera, r, voxel, folder / f"occupancy_3d_{frame:06d}.png")


def occupancy_3d(semantics: npt.NDArray[np.uint8], observed: npt.NDArray[np.bool_], r: npt.NDArray[np.float64],
                 voxel: float, path: Path) -> None:  # fmt: skip
    """The observed occupied voxels within 25 m as points in 3D, seen from behind and above."""
    occupied = (semantics != FREE_NATIVE) & observed
    ijk = np.argwhere(occupied)
    xyz = r[:3] + (ijk + 0.5) * voxel
    near = np.all(np.abs(xyz[:, :2]) <= 25.0, axis=1)
    xyz, classes = xyz[near], semantics[occupied][near]
    fig = plt.figure(figsize=(10, 8))
    ax: Any = fig.add_subplot(projection="3d")
    colours = np.asarray([_colour(int(c)) for c in classes.tolist()]).reshape(-1, 3)
    ax.scatter(xyz[:, 0], xyz[:, 1], xyz[:, 2], c=colours, s=2.0, marker="s", depthshade=False)
    ax.set_box_aspect((50, 50, float(r[5] - r[2])))
    ax.view_init(elev=35, azim=-150)
    ax.set_xlabel("x (m)")
    ax.set_ylabel("y (m)")
    ax.set_zlabel("z (m)")
    ax.set_title("observed occupied voxels within 25 m")
    fig.tight_layout()
    fig.savefig(path, dpi=80)
    plt.close(fig)
