"""Robot model files the simulator loads."""
from __future__ import annotations

import os
import tempfile
from pathlib import Path

from ..robot import panda_urdf_path


def lowpoly_panda_urdf() -> str:
    """pybullet_data's panda.urdf with visual meshes swapped for the collision meshes.

    TinyRenderer's cost is dominated by the Panda's detailed visual meshes (30 ms vs 1.6 ms for an
    84x84 image); dynamics and collision geometry are unchanged. Written once to a per-user temp dir.
    """
    src = panda_urdf_path()
    mesh_dir = os.path.join(os.path.dirname(src), "meshes")
    text = Path(src).read_text().replace("meshes/visual/", "meshes/collision/").replace("package://meshes", mesh_dir)
    return generated_urdf("panda_lowpoly.urdf", text)


def generated_urdf(name: str, text: str) -> str:
    """Path of `text` as <per-user temp dir>/name, rewritten only when it differs, atomically (processes
    that build worlds side by side never load a half-written file)."""
    out = Path(tempfile.gettempdir()) / f"skillgen_ros_{os.getuid()}" / name
    if not out.exists() or out.read_text() != text:
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = out.with_name(f".{out.name}.{os.getpid()}")
        tmp.write_text(text)
        tmp.replace(out)
    return str(out)
