"""Named contact models: how the simulated hand holds what it grasps.

pybullet_data's panda.urdf grips with its bare convex finger meshes and soft finger contact
(`<stiffness value="30000"/>`, `<damping value="1000"/>` on each finger link), and pybullet runs 50
solver iterations here. robosuite's Panda grips with pad boxes (models/assets/grippers/panda_gripper.xml
`finger1_pad_collision` / `finger2_pad_collision`). bench/datagen/contact_model.py measured the
difference on Threading D0 (paper profile, 80 attempts): 18/80 on `pybullet`, 44/80 with the pads and
200 solver iterations (the needle turned 11-15 deg in the hand over a failed transfer on `pybullet`).

- `pybullet` (the default): the sim every shipped result was measured on.
- `robosuite_pads`: robosuite's pads on each finger, rigid finger contact, 200 solver iterations.
  Source demos must be made on the same model (`skillgen demos make --contact-model robosuite_pads`).

A model is a set of SimConfig fields, so SimWorld(**contact_settings(name)) builds it.
"""
from __future__ import annotations

import re
from dataclasses import dataclass
from pathlib import Path

from ..errors import InvalidInputError
from .assets import generated_urdf


@dataclass(frozen=True)
class ContactModel:
    finger_pads: bool
    solver_iterations: int


CONTACT_MODELS = {
    "pybullet": ContactModel(finger_pads=False, solver_iterations=50),
    "robosuite_pads": ContactModel(finger_pads=True, solver_iterations=200),
}
DEFAULT_CONTACT_MODEL = "pybullet"

# robosuite panda_gripper.xml: the pad box's half size and its centre in the finger frame. robosuite's finger
# frame sits 0.0524 m below its grip site (0.097), ours 0.0584 m below panda_grasptarget (0.1034): the same pad,
# 3.6 mm above the grip point, is at z 0.043 here; its face toward the other finger 0.5 mm proud of the mesh.
PAD_HALF = (0.008, 0.004, 0.008)
PAD_CENTER_Y, PAD_CENTER_Z = 0.0035, 0.043
FINGER_LINKS = (("panda_leftfinger", PAD_CENTER_Y), ("panda_rightfinger", -PAD_CENTER_Y))


def contact_settings(name: str) -> dict:
    """The SimConfig fields of a named contact model; INVALID_PARAMETER for an unknown name."""
    if name not in CONTACT_MODELS:
        raise InvalidInputError(f"unknown contact model {name!r}; known: {sorted(CONTACT_MODELS)}",
                                "INVALID_PARAMETER")
    m = CONTACT_MODELS[name]
    return {"finger_pads": m.finger_pads, "solver_iterations": m.solver_iterations}


def pads_urdf(text: str) -> str:
    """panda.urdf text with robosuite's finger pads added and the fingers' soft contact removed."""
    for link, y in FINGER_LINKS:
        a = text.index(f'<link name="{link}"')
        b = text.index("</link>", a)
        body = re.sub(r"\s*<stiffness[^>]*/>\s*<damping[^>]*/>", "", text[a:b])
        size = " ".join(f"{2 * h:g}" for h in PAD_HALF)
        pad = (f'  <collision>\n      <origin rpy="0 0 0" xyz="0 {y:g} {PAD_CENTER_Z:g}"/>\n      <geometry>\n'
               f'        <box size="{size}"/>\n      </geometry>\n    </collision>\n  ')
        text = text[:a] + body + pad + text[b:]
    return text


def with_finger_pads(urdf: str) -> str:
    """Path of a copy of `urdf` with the pads, in the per-user temp dir (as assets.lowpoly_panda_urdf)."""
    src = Path(urdf)
    text = pads_urdf(src.read_text()).replace("package://meshes", str(src.parent / "meshes"))
    return generated_urdf(f"{src.stem}_pads.urdf", text)
