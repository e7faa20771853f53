"""/robot_description (the Panda URDF) with mesh URIs Foxglove resolves, and those meshes.

pybullet_data's panda.urdf names its meshes `package://meshes/...`, a package called "meshes"
that exists nowhere. We rewrite them to `package://franka_panda/meshes/...`, the folder's real
name under pybullet_data, so that:
- the live view (`skillgen view`) serves them itself through the Foxglove WebSocket protocol's
  fetchAsset (`resolve_package_uri`), with no client setting;
- a bag opened in Foxglove desktop resolves them with its "ROS package path" setting set to
  `package_path()` (pybullet_data's folder; `skillgen view --package-path` prints it).
Meshes are not embedded in the bag: 9 MB of OBJ per bag for a picture a setting gives.
"""
from __future__ import annotations

import functools
import re
from pathlib import Path

from ..robot import panda_urdf_path

PACKAGE = "franka_panda"
_MESH = re.compile(r'filename="package://meshes/')


def package_path() -> str:
    """The folder that holds the `franka_panda` package (Foxglove's ROS package path)."""
    return str(Path(panda_urdf_path()).parent.parent)


@functools.lru_cache(maxsize=1)
def robot_description() -> str:
    """The Panda URDF text, meshes as package://franka_panda/meshes/..."""
    return _MESH.sub(f'filename="package://{PACKAGE}/meshes/', Path(panda_urdf_path()).read_text())


def resolve_package_uri(uri: str) -> Path | None:
    """The file a package://franka_panda/... URI names, or None (other packages, escapes, missing)."""
    prefix = f"package://{PACKAGE}/"
    if not uri.startswith(prefix):
        return None
    root = Path(panda_urdf_path()).parent.resolve()
    path = (root / uri[len(prefix):]).resolve()
    if root not in path.parents or not path.is_file():
        return None
    return path
