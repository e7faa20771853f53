"""Sphere collision model: covers the meshes, conservative vs pybullet, boxes, clouds, attached."""
import numpy as np
import pybullet as pb
import pytest
import yaml

from skillgen_ros.core.planning.collision import (SPHERES_FILE, AllowedContacts, AttachedObject,
                                                  Box, CollisionModel)
from skillgen_ros.core.planning.kinematics import LINKS, PandaKinematics
from skillgen_ros.core.robot import ARM_JOINTS, FINGER_JOINTS, Q_HOME, panda_urdf_path


@pytest.fixture(scope="module")
def cm():
    return CollisionModel(PandaKinematics())


def _box(name, xyz, half):
    T = np.eye(4)
    T[:3, 3] = xyz
    return Box(name, T, half)


def test_fitted_spheres_cover_the_meshes(cm):
    """Independent check: surface samples of each mesh's convex hull (what pybullet collides
    with; it contains the mesh), posed at a random configuration, lie inside the spheres."""
    import open3d as o3d

    from skillgen_ros.core.planning.sphere_fit import SPEC, _load

    data = yaml.safe_load(SPHERES_FILE.read_text())
    assert all(L["held_out_covered"] == 1.0 for L in data["links"].values())
    o3d.utility.random.seed(7)
    q = np.random.default_rng(0).uniform(cm.kin.lower, cm.kin.upper)
    poses = cm.kin.link_poses(q)
    S = cm.sphere_world(q)
    for link, (fname, _) in SPEC.items():
        P = np.asarray(_load(fname).sample_points_uniformly(3000).points)
        P = P @ poses[link][:3, :3].T + poses[link][:3, 3]
        d = np.linalg.norm(P[:, None] - S[None, :, :3], axis=2) - S[None, :, 3]
        assert np.all(d.min(axis=1) <= 1e-4), link


def test_self_collision_is_conservative_vs_pybullet_meshes(cm):
    """Whenever pybullet finds two checked links touching, the sphere model reports collision."""
    cid = pb.connect(pb.DIRECT)
    try:
        body = pb.loadURDF(panda_urdf_path(), useFixedBase=True, physicsClientId=cid)
        idx = {pb.getJointInfo(body, i, physicsClientId=cid)[1].decode(): i
               for i in range(pb.getNumJoints(body, physicsClientId=cid))}
        lidx = {pb.getJointInfo(body, i, physicsClientId=cid)[12].decode(): i
                for i in range(pb.getNumJoints(body, physicsClientId=cid))}
        lidx["panda_link0"] = -1
        rng = np.random.default_rng(3)
        Q = rng.uniform(cm.kin.lower, cm.kin.upper, size=(300, 7))
        ours = cm.in_collision(Q)
        touching = 0
        for q, hit in zip(Q, ours):
            for n, v in zip(ARM_JOINTS, q):
                pb.resetJointState(body, idx[n], v, physicsClientId=cid)
            for n in FINGER_JOINTS:
                pb.resetJointState(body, idx[n], 0.04, physicsClientId=cid)
            for a, b in cm.link_pairs:
                pts = pb.getClosestPoints(body, body, 0.0, lidx[LINKS[a]], lidx[LINKS[b]],
                                          physicsClientId=cid)
                if any(p[8] < -1e-3 for p in pts):
                    touching += 1
                    assert hit, (q, LINKS[a], LINKS[b])
        assert touching > 0  # the sample did contain real self-contacts
    finally:
        pb.disconnect(cid)


def test_home_is_free_and_table_blocks_going_below(cm):
    cm.set_boxes([])
    cm.set_point_cloud(np.empty((0, 3)))
    assert not cm.in_collision(Q_HOME)[0]
    q_low = np.array([0.0, 1.7, 0.0, -0.5, 0.0, 2.2, 0.785])  # reaching into the table
    assert cm.kin.fk(q_low)[2, 3] < 0.0
    assert cm.in_collision(q_low)[0]


def test_boxes_and_allowed_contacts(cm):
    p = cm.kin.fk(Q_HOME)[:3, 3]
    cm.set_boxes([_box("cube", p, [0.02, 0.02, 0.02])])
    assert cm.in_collision(Q_HOME)[0]
    assert not cm.in_collision(Q_HOME, allow=AllowedContacts(hand_object="cube"))[0]
    cm.set_boxes([_box("far", [0.0, 0.8, 0.3], [0.05, 0.05, 0.05])])
    assert not cm.in_collision(Q_HOME)[0]
    cm.set_boxes([])


def test_point_cloud_margin_empty_cloud_and_self_filter(cm):
    cm.set_boxes([])
    T_hand = cm.kin.link_poses(Q_HOME)["panda_hand"]
    palm = T_hand[:3, 3] + 0.03 * T_hand[:3, 2]
    assert cm.set_point_cloud(np.empty((0, 3))) == 0
    assert not cm.in_collision(Q_HOME)[0]  # empty cloud = no obstacles
    cm.set_point_cloud(palm[None])
    assert cm.in_collision(Q_HOME)[0]
    # the cloud margin: a point just outside the sphere cover still counts, a far one does not
    S = cm.sphere_world(Q_HOME)
    i = int(np.argmax(S[:, 2]))  # topmost sphere, nothing else above it
    cm.set_point_cloud(S[i, :3][None] + [0, 0, S[i, 3] + 0.5 * cm.cloud_margin])
    assert cm.in_collision(Q_HOME)[0]
    cm.set_point_cloud(S[i, :3][None] + [0, 0, S[i, 3] + 2.0 * cm.cloud_margin])
    assert not cm.in_collision(Q_HOME)[0]
    # the robot's own points are filtered at the start configuration
    own = cm.sphere_world(Q_HOME)[:, :3]
    assert cm.set_point_cloud(own, self_filter_q=Q_HOME) == 0
    far = np.random.default_rng(0).uniform([0.4, 0.5, 0.1], [0.6, 0.7, 0.3], size=(500, 3))
    assert cm.set_point_cloud(np.vstack([own, far]), self_filter_q=Q_HOME) == 500
    assert not cm.in_collision(Q_HOME)[0]
    cm.set_point_cloud(np.empty((0, 3)))


def test_attached_object_collides_and_edges_validate_in_one_call(cm):
    T_ee = cm.kin.fk(Q_HOME)
    below = np.eye(4)
    below[2, 3] = 0.06  # object 6 cm further along the gripper z (it hangs below the fingers)
    obj = AttachedObject.from_box("cube", [0.025, 0.025, 0.025], below)
    tip = (T_ee @ below)[:3, 3]
    cm.set_boxes([_box("post", tip + [0, 0, -0.04], [0.02, 0.02, 0.01])])
    assert not cm.in_collision(Q_HOME)[0]  # the empty hand clears the post
    assert cm.in_collision(Q_HOME, attached=obj)[0]  # the held cube does not
    q1 = Q_HOME + np.array([0.8, 0, 0, 0, 0, 0, 0])
    Q = Q_HOME + np.linspace(0, 1, 41)[:, None] * (q1 - Q_HOME)
    per_state = np.array([cm.in_collision(q[None], attached=obj)[0] for q in Q])
    np.testing.assert_array_equal(cm.in_collision(Q, attached=obj), per_state)
    assert cm.check_motion(Q_HOME, q1, attached=obj) == (not per_state.any())
    assert len(cm.motion_samples(Q_HOME, q1, attached=obj)) > len(cm.motion_samples(Q_HOME, q1))
    cm.set_boxes([])
