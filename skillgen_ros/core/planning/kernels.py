"""numba kernels for the Panda chain: batched FK and the inner IK iterations.

Why numba: the IK needs hundreds of tiny 4x4/6x6 products per millisecond, which numpy cannot do
(each numpy call costs microseconds of overhead). The kernels take the joint placements read from
pinocchio by `PandaKinematics`, so the chain has one source of truth; tests compare them with
pinocchio and pybullet. All joints of the Panda rotate about their local z axis.
"""
from __future__ import annotations

import warnings

import numpy as np

try:
    from numba import njit
except ImportError:  # still correct without numba, only far slower (IK then misses its 5 ms)
    warnings.warn("numba not installed: planning kernels run as plain Python", RuntimeWarning)

    def njit(*args, **kwargs):
        if len(args) == 1 and callable(args[0]) and not kwargs:
            return args[0]
        return lambda f: f


@njit(cache=True)
def seed_rng(seed):
    np.random.seed(seed)


@njit(cache=True, inline="always")
def _mul_rz(A, c, s, out):
    """out = A @ Rz(theta) for 4x4 A (c, s = cos, sin theta)."""
    for r in range(4):
        a0 = A[r, 0]
        a1 = A[r, 1]
        out[r, 0] = a0 * c + a1 * s
        out[r, 1] = -a0 * s + a1 * c
        out[r, 2] = A[r, 2]
        out[r, 3] = A[r, 3]


@njit(cache=True, inline="always")
def _matmul4(A, B, out):
    for r in range(4):
        for c in range(4):
            out[r, c] = A[r, 0] * B[0, c] + A[r, 1] * B[1, c] + A[r, 2] * B[2, c] + A[r, 3] * B[3, c]


@njit(cache=True)
def _solve_dls(J, e, lam, dq):
    """dq = J^T (J J^T + lam I)^-1 e via a 6x6 Cholesky, no allocation beyond two small arrays."""
    A = np.empty((6, 6))
    for r in range(6):
        for c in range(r + 1):
            acc = 0.0
            for j in range(7):
                acc += J[r, j] * J[c, j]
            A[r, c] = acc
    for r in range(6):
        A[r, r] += lam
    L = np.zeros((6, 6))
    for r in range(6):
        for c in range(r + 1):
            acc = A[r, c]
            for k in range(c):
                acc -= L[r, k] * L[c, k]
            if r == c:
                L[r, r] = np.sqrt(max(acc, 1e-300))
            else:
                L[r, c] = acc / L[c, c]
    y = np.empty(6)
    for r in range(6):
        acc = e[r]
        for k in range(r):
            acc -= L[r, k] * y[k]
        y[r] = acc / L[r, r]
    for r in range(5, -1, -1):
        acc = y[r]
        for k in range(r + 1, 6):
            acc -= L[k, r] * y[k]
        y[r] = acc / L[r, r]
    for j in range(7):
        acc = 0.0
        for r in range(6):
            acc += J[r, j] * y[r]
        dq[j] = acc


@njit(cache=True)
def joint_frames(q, joint_T, frames):
    """frames[0] = I, frames[i+1] = frames[i] @ joint_T[i] @ Rz(q[i])."""
    tmp = np.empty((4, 4))
    for r in range(4):
        for c in range(4):
            frames[0, r, c] = 1.0 if r == c else 0.0
    for i in range(7):
        _matmul4(frames[i], joint_T[i], tmp)
        _mul_rz(tmp, np.cos(q[i]), np.sin(q[i]), frames[i + 1])


@njit(cache=True)
def link_poses_batch(Q, joint_T, link_parent, link_T):
    """(N,7) -> (N,L,4,4) world poses of the links (parent joint frame @ fixed placement)."""
    n = Q.shape[0]
    L = link_parent.shape[0]
    out = np.empty((n, L, 4, 4))
    frames = np.empty((8, 4, 4))
    for k in range(n):
        joint_frames(Q[k], joint_T, frames)
        for l in range(L):
            _matmul4(frames[link_parent[l]], link_T[l], out[k, l])
    return out


@njit(cache=True)
def _rotvec(R):
    c = (R[0, 0] + R[1, 1] + R[2, 2] - 1.0) * 0.5
    c = min(1.0, max(-1.0, c))
    vx = 0.5 * (R[2, 1] - R[1, 2])
    vy = 0.5 * (R[0, 2] - R[2, 0])
    vz = 0.5 * (R[1, 0] - R[0, 1])
    s = np.sqrt(vx * vx + vy * vy + vz * vz)
    th = np.arctan2(s, c)
    out = np.empty(3)
    if c < -0.999:
        # near pi: axis from the symmetric part, sign from the skew part
        ax = np.sqrt(max(0.0, (R[0, 0] - c) / (1.0 - c)))
        ay = np.sqrt(max(0.0, (R[1, 1] - c) / (1.0 - c)))
        az = np.sqrt(max(0.0, (R[2, 2] - c) / (1.0 - c)))
        if ax >= ay and ax >= az:
            ay = np.copysign(ay, R[0, 1] + R[1, 0])
            az = np.copysign(az, R[0, 2] + R[2, 0])
            if vx < 0:
                ax, ay, az = -ax, -ay, -az
        elif ay >= az:
            ax = np.copysign(ax, R[0, 1] + R[1, 0])
            az = np.copysign(az, R[1, 2] + R[2, 1])
            if vy < 0:
                ax, ay, az = -ax, -ay, -az
        else:
            ax = np.copysign(ax, R[0, 2] + R[2, 0])
            ay = np.copysign(ay, R[1, 2] + R[2, 1])
            if vz < 0:
                ax, ay, az = -ax, -ay, -az
        n = np.sqrt(ax * ax + ay * ay + az * az)
        out[0] = ax / n * th
        out[1] = ay / n * th
        out[2] = az / n * th
        return out
    f = 1.0 if s < 1e-12 else th / s
    out[0] = vx * f
    out[1] = vy * f
    out[2] = vz * f
    return out


@njit(cache=True)
def ee_error_jacobian(q, T_target, joint_T, ee_parent, ee_T, frames, e, J):
    """6-D world-frame error [p_t - p; log(R_t R^T)] and the matching geometric Jacobian."""
    joint_frames(q, joint_T, frames)
    T = np.empty((4, 4))
    _matmul4(frames[ee_parent], ee_T, T)
    for r in range(3):
        e[r] = T_target[r, 3] - T[r, 3]
    Rerr = np.empty((3, 3))
    for r in range(3):
        for c in range(3):
            Rerr[r, c] = T_target[r, 0] * T[c, 0] + T_target[r, 1] * T[c, 1] + T_target[r, 2] * T[c, 2]
    e[3:] = _rotvec(Rerr)
    for j in range(7):
        F = frames[j + 1]
        zx, zy, zz = F[0, 2], F[1, 2], F[2, 2]
        dx, dy, dz = T[0, 3] - F[0, 3], T[1, 3] - F[1, 3], T[2, 3] - F[2, 3]
        J[0, j] = zy * dz - zz * dy
        J[1, j] = zz * dx - zx * dz
        J[2, j] = zx * dy - zy * dx
        J[3, j] = zx
        J[4, j] = zy
        J[5, j] = zz


@njit(cache=True)
def ik_iterate(Q, state, T_target, joint_T, ee_parent, ee_T, lower, upper, newton_rows,
               tol, n_iters, max_age, restart=True):
    """Run up to n_iters batched iterations; return a bool mask of rows within `tol`.

    state[:, 0] = best error so far, state[:, 1] = iterations since a 10% improvement,
    state[:, 2] = age of the row's seed. Stalled or old rows are re-seeded uniformly (unless
    restart is False: local tracking must stay on its branch).
    Newton rows: dq = J^T (J J^T + lam I)^-1 e. Bounded rows: the same after freezing joints that
    sit on a limit and whose step points outward (one active-set pass).
    """
    n = Q.shape[0]
    frames = np.empty((8, 4, 4))
    e = np.empty(6)
    J = np.empty((6, 7))
    dq = np.empty(7)
    done = np.zeros(n, np.bool_)
    for it in range(n_iters):
        for k in range(n):
            q = Q[k]
            ee_error_jacobian(q, T_target, joint_T, ee_parent, ee_T, frames, e, J)
            err = np.sqrt(np.sum(e * e))
            if err < tol:
                done[k] = True
                continue
            if err < 0.9 * state[k, 0]:
                state[k, 0] = err
                state[k, 1] = 0
            else:
                state[k, 1] += 1
            state[k, 2] += 1
            if restart and (state[k, 1] > 4 or state[k, 2] > max_age):
                for j in range(7):
                    Q[k, j] = np.random.uniform(lower[j], upper[j])
                state[k, 0] = np.inf
                state[k, 1] = 0
                state[k, 2] = 0
                continue
            lam = 1e-9 + 1e-3 * min(err * err, 1.0)
            _solve_dls(J, e, lam, dq)
            if not newton_rows[k]:
                any_active = False
                for j in range(7):
                    if (q[j] <= lower[j] + 1e-9 and dq[j] < 0) or (q[j] >= upper[j] - 1e-9 and dq[j] > 0):
                        any_active = True
                        for r in range(6):
                            J[r, j] = 0.0
                if any_active:
                    _solve_dls(J, e, lam, dq)
            m = np.max(np.abs(dq))
            scale = 1.0 if m <= 1.0 else 1.0 / m
            for j in range(7):
                Q[k, j] = min(upper[j], max(lower[j], q[j] + dq[j] * scale))
        if np.any(done):
            break
    return done


@njit(cache=True)
def sphere_centres(Q, joint_T, link_parent, link_T, sph_link, sph_c):
    """(N,7) -> (N,S,3) world centres of spheres given in their link frames."""
    n = Q.shape[0]
    S = sph_c.shape[0]
    L = link_parent.shape[0]
    out = np.empty((n, S, 3))
    frames = np.empty((8, 4, 4))
    links = np.empty((L, 4, 4))
    for k in range(n):
        joint_frames(Q[k], joint_T, frames)
        for l in range(L):
            _matmul4(frames[link_parent[l]], link_T[l], links[l])
        for s in range(S):
            T = links[sph_link[s]]
            c = sph_c[s]
            for r in range(3):
                out[k, s, r] = T[r, 0] * c[0] + T[r, 1] * c[1] + T[r, 2] * c[2] + T[r, 3]
    return out


@njit(cache=True)
def collide_spheres(C, radii, pair_a, pair_b, box_inv, box_half, box_skip, table_z, table_check,
                    margin):
    """Per configuration: True if any sphere hits a box, the table, or a self-collision pair.

    C (N,S,3) world centres; box_inv (B,4,4) world->box; box_skip (S,B) allowed contacts;
    table_check (S,) spheres checked against the half-space z < table_z.
    """
    n, S = C.shape[0], C.shape[1]
    B = box_inv.shape[0]
    hit = np.zeros(n, np.bool_)
    for k in range(n):
        found = False
        for s in range(S):
            x, y, z = C[k, s, 0], C[k, s, 1], C[k, s, 2]
            r = radii[s] + margin
            if table_check[s] and z - r < table_z:
                found = True
                break
            for b in range(B):
                if box_skip[s, b]:
                    continue
                M = box_inv[b]
                d2 = 0.0
                for a in range(3):
                    v = M[a, 0] * x + M[a, 1] * y + M[a, 2] * z + M[a, 3]
                    h = box_half[b, a]
                    if v > h:
                        d2 += (v - h) * (v - h)
                    elif v < -h:
                        d2 += (v + h) * (v + h)
                if d2 < r * r:
                    found = True
                    break
            if found:
                break
        if not found:
            for p in range(pair_a.shape[0]):
                i, j = pair_a[p], pair_b[p]
                dx = C[k, i, 0] - C[k, j, 0]
                dy = C[k, i, 1] - C[k, j, 1]
                dz = C[k, i, 2] - C[k, j, 2]
                rr = radii[i] + radii[j]
                if dx * dx + dy * dy + dz * dz < rr * rr:
                    found = True
                    break
        hit[k] = found
    return hit
