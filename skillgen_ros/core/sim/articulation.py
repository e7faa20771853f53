"""Articulated task objects in pybullet: a fixed base with links on revolute / prismatic joints.

One pybullet multibody per object (createMultiBody with links, no URDF file): the base is the
object's fixed parts (mass 0: static, like every fixture), each link its `Link.parts` at the
joint frame `Joint.origin` (core/tasks/articulation.py). A joint gets the spec's limits, its damping,
and Coulomb friction as a velocity motor with target 0 and the friction as its force (pybullet's usual
joint friction), so a lid or drawer stays where the hand left it unless gravity beats the friction.
Joint values read back as {articulation.joint_key: value}, as SceneState.joints carries them.
"""
from __future__ import annotations

import numpy as np

from ..errors import InvalidInputError
from ..tasks.articulation import BASE, joint_key
from ..tasks.spec import ObjectSpec
from ..tasks.shapes import Part

LIMIT_FORCE = 1000.0   # N m / N the joint limits may push with (pybullet jointLimitForce)
MAX_COMPOUND = 16      # children pybullet keeps in one compound shape


def shape_arrays(p, parts: tuple[Part, ...], color) -> tuple[int, int]:
    """(collision, visual) compound shapes of primitive parts, in the frame they are given in."""
    kinds = [p.GEOM_BOX if q.kind == "box" else p.GEOM_CYLINDER for q in parts]
    common = dict(shapeTypes=kinds, halfExtents=[list(q.size) for q in parts],
                  radii=[q.size[0] for q in parts], lengths=[2 * q.size[1] for q in parts])
    pos, orn = [list(q.position) for q in parts], [list(q.quaternion) for q in parts]
    col = p.createCollisionShapeArray(**common, collisionFramePositions=pos, collisionFrameOrientations=orn)
    vis = p.createVisualShapeArray(**common, visualFramePositions=pos, visualFrameOrientations=orn,
                                   rgbaColors=[list(color)] * len(parts))
    return col, vis


def spawn(p, o: ObjectSpec, pose) -> int:
    """The fixture's multibody at `pose` (object frame), its joints at their initial values.

    pybullet keeps at most MAX_COMPOUND children of a compound shape (more are silently dropped, and a
    larger visual array crashes it): the base's parts beyond the first MAX_COMPOUND ride on static links
    fixed to the base, after the jointed links (so joint k is pybullet joint k)."""
    if o.mass > 0:
        raise InvalidInputError(f"object {o.id}: articulated or many-part objects must be fixtures (mass 0)")
    chunks = [o.parts[k:k + MAX_COMPOUND] for k in range(0, len(o.parts), MAX_COMPOUND)]
    col, vis = shape_arrays(p, chunks[0], o.color)
    index = {lk.name: k + 1 for k, lk in enumerate(o.links)}   # pybullet: 0 = the base, links from 1
    links = {lk.name: lk for lk in o.links}
    shapes = [shape_arrays(p, links[j.child].parts, links[j.child].color) for j in o.joints]
    shapes += [shape_arrays(p, c, o.color) for c in chunks[1:]]
    fixed = len(chunks) - 1
    types = {"revolute": p.JOINT_REVOLUTE, "prismatic": p.JOINT_PRISMATIC}
    body = p.createMultiBody(
        0.0, col, vis, pose.position.tolist(), pose.quaternion.tolist(),
        linkMasses=[links[j.child].mass for j in o.joints] + [0.0] * fixed,
        linkCollisionShapeIndices=[c for c, _ in shapes], linkVisualShapeIndices=[v for _, v in shapes],
        linkPositions=[list(j.origin) for j in o.joints] + [[0.0, 0.0, 0.0]] * fixed,
        linkOrientations=[list(j.origin_quat) for j in o.joints] + [[0.0, 0.0, 0.0, 1.0]] * fixed,
        linkInertialFramePositions=[links[j.child].center_of_mass().tolist() for j in o.joints] + [[0.0] * 3] * fixed,
        linkInertialFrameOrientations=[[0.0, 0.0, 0.0, 1.0]] * (len(o.joints) + fixed),
        linkParentIndices=[0 if j.parent == BASE else index[j.parent] for j in o.joints] + [0] * fixed,
        linkJointTypes=[types[j.type] for j in o.joints] + [p.JOINT_FIXED] * fixed,
        linkJointAxis=[list(j.axis) for j in o.joints] + [[0.0, 0.0, 1.0]] * fixed)
    for k in range(-1, len(o.joints) + fixed):
        p.changeDynamics(body, k, lateralFriction=o.friction, frictionAnchor=1, linearDamping=0.0, angularDamping=0.0)
    for k, j in enumerate(o.joints):
        p.changeDynamics(body, k, jointLowerLimit=j.lower, jointUpperLimit=j.upper, jointLimitForce=LIMIT_FORCE,
                         jointDamping=j.damping)
        p.resetJointState(body, k, j.initial, 0.0)
        p.setJointMotorControl2(body, k, p.VELOCITY_CONTROL, targetVelocity=0.0, force=j.friction)
    return body


def read(p, body: int, o: ObjectSpec) -> tuple[dict[str, float], np.ndarray]:
    """({joint_key: value}, velocities in joint order) of the object's joints."""
    states = p.getJointStates(body, list(range(len(o.joints))))
    return ({joint_key(o.id, j.name): float(s[0]) for j, s in zip(o.joints, states)},
            np.array([s[1] for s in states], float))


def write(p, body: int, o: ObjectSpec, values, velocities=None) -> None:
    """Set the joints (in joint order) kinematically: a restored state or a re-shown step."""
    velocities = np.zeros(len(o.joints)) if velocities is None else velocities
    for k in range(len(o.joints)):
        p.resetJointState(body, k, float(values[k]), float(velocities[k]))


# ---- a world's articulated objects ({object id: ObjectSpec} in scene order, bodies {object id: body})
def values(p, bodies, articulated) -> dict[str, float]:
    """{joint_key: value} of every articulated object's joints."""
    return {k: v for oid, o in articulated.items() for k, v in read(p, bodies[oid], o)[0].items()}


def state_size(articulated) -> int:
    return 2 * sum(len(o.joints) for o in articulated.values())


def state(p, bodies, articulated) -> np.ndarray:
    """[value, velocity] per joint, objects in scene order (SimWorld.get_state's joint block)."""
    out = [np.column_stack([list(v.values()), qd]).reshape(-1)
           for v, qd in (read(p, bodies[oid], o) for oid, o in articulated.items())]
    return np.concatenate(out) if out else np.zeros(0)


def set_state(p, bodies, articulated, s) -> None:
    """Restore a `state()` block (extra trailing values are ignored)."""
    k = 0
    for oid, o in articulated.items():
        j = np.asarray(s[k: k + 2 * len(o.joints)], float).reshape(-1, 2)
        write(p, bodies[oid], o, j[:, 0], j[:, 1])
        k += 2 * len(o.joints)


def show(p, bodies, articulated, joints) -> None:
    """Set the joints named in {joint_key: value}; the others keep their values."""
    for oid, o in articulated.items():
        now = read(p, bodies[oid], o)[0]
        write(p, bodies[oid], o, [joints.get(k, v) for k, v in now.items()])
