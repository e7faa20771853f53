"""Kinematics: pinocchio FK and the numba batch FK agree with pybullet's own link states."""
import numpy as np
import pybullet as pb
import pytest
from scipy.spatial.transform import Rotation

from skillgen_ros.core.errors import InvalidInputError
from skillgen_ros.core.planning.kinematics import LINKS, PandaKinematics
from skillgen_ros.core.robot import ARM_JOINTS, EE_LINK, FINGER_JOINTS, panda_urdf_path


@pytest.fixture(scope="module")
def kin():
    return PandaKinematics()


@pytest.fixture(scope="module")
def bullet():
    cid = pb.connect(pb.DIRECT)
    body = pb.loadURDF(panda_urdf_path(), useFixedBase=True, physicsClientId=cid)
    joints, links = {}, {}
    for i in range(pb.getNumJoints(body, physicsClientId=cid)):
        info = pb.getJointInfo(body, i, physicsClientId=cid)
        joints[info[1].decode()] = i
        links[info[12].decode()] = i
    yield cid, body, joints, links
    pb.disconnect(cid)


def _bullet_pose(cid, body, link):
    s = pb.getLinkState(body, link, computeForwardKinematics=True, physicsClientId=cid)
    return np.array(s[4]), Rotation.from_quat(s[5]).as_matrix()


def test_fk_matches_pybullet(kin, bullet):
    cid, body, joints, links = bullet
    rng = np.random.default_rng(0)
    for q in rng.uniform(kin.lower, kin.upper, size=(50, 7)):
        for name, v in zip(ARM_JOINTS, q):
            pb.resetJointState(body, joints[name], v, physicsClientId=cid)
        for name in FINGER_JOINTS:
            pb.resetJointState(body, joints[name], 0.04, physicsClientId=cid)
        T = kin.fk(q)
        p, R = _bullet_pose(cid, body, links[EE_LINK])
        assert np.linalg.norm(T[:3, 3] - p) < 1e-6
        assert Rotation.from_matrix(T[:3, :3] @ R.T).magnitude() < 1e-6
        poses = kin.link_poses(q)
        for name in LINKS[1:]:
            p, R = _bullet_pose(cid, body, links[name])
            assert np.linalg.norm(poses[name][:3, 3] - p) < 1e-6, name
            assert Rotation.from_matrix(poses[name][:3, :3] @ R.T).magnitude() < 1e-6, name


def test_batch_fk_matches_pinocchio(kin):
    Q = np.random.default_rng(1).uniform(kin.lower, kin.upper, size=(20, 7))
    batch = kin.link_poses_batch(Q)
    ee = kin.fk_batch(Q)
    for k, q in enumerate(Q):
        np.testing.assert_allclose(ee[k], kin.fk(q), atol=1e-12)
        for i, name in enumerate(LINKS):
            np.testing.assert_allclose(batch[k, i], kin.link_poses(q)[name], atol=1e-12)


def test_jacobian_matches_finite_differences(kin):
    q = np.random.default_rng(2).uniform(kin.lower, kin.upper)
    J = kin.jacobian(q)
    eps = 1e-7
    for j in range(7):
        dq = np.zeros(7)
        dq[j] = eps
        T1, T0 = kin.fk(q + dq), kin.fk(q - dq)
        np.testing.assert_allclose((T1[:3, 3] - T0[:3, 3]) / (2 * eps), J[:3, j], atol=1e-6)
        w = Rotation.from_matrix(T1[:3, :3] @ T0[:3, :3].T).as_rotvec() / (2 * eps)
        np.testing.assert_allclose(w, J[3:, j], atol=1e-6)


def test_bad_configuration_is_rejected(kin):
    with pytest.raises(InvalidInputError):
        kin.fk([0.0] * 6)
    with pytest.raises(InvalidInputError):
        kin.fk([np.nan] * 7)
