"""From per-body local rotations to the character's hinge angles (numpy).

Every 3-hinge body (three hinges about distinct axes, composed by MuJoCo as intrinsic Euler angles
in chain order: x, y, z for most bodies, y, x, z for the hips) has two Euler
solutions for the same rotation, ``(a, b, c)`` and ``(a + pi, pi - b, c + pi)``, each defined up
to multiples of 2*pi. All of them give exactly the same body poses, but they differ for the
physics: a PD target outside the joint range cannot be reached. So:

* each angle is wrapped into ``[mid - pi, mid + pi)`` around the middle of its joint range, which
  minimises the range violation and puts the 2*pi seam as far from the range as possible;
* per 3-hinge body the branch is chosen per frame by a two-state Viterbi path that minimises the
  total range violation plus the joint-space distance travelled between frames, so the branch
  only switches when that keeps the angles in range for long enough to pay for the jump.

1-hinge bodies (knees, elbows) take the twist angle about their hinge axis; off-axis parts of
the file's rotation are dropped (they are exactly zero in the shared data).
"""

from __future__ import annotations

from collections.abc import Sequence

import warnings

import numpy as np

from jaxmotion.motion import rotations as rot
from jaxmotion.physics.character import Character


def range_wrap(angle: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Wraps angles into ``[mid - pi, mid + pi)``, ``mid = (lo + hi) / 2``. [..., n] -> [..., n]."""
    mid = 0.5 * (lo + hi)
    return mid + np.mod(angle - mid + np.pi, 2 * np.pi) - np.pi


def range_violation(angle: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """How far each angle lies outside [lo, hi] (0 inside), radians. [..., n] -> [..., n]."""
    return np.maximum(np.maximum(lo - angle, angle - hi), 0.0)


def euler_from_quat(q: np.ndarray, axes: Sequence[int] = (0, 1, 2)) -> np.ndarray:
    """Intrinsic Euler angles about three distinct axes in the given order (MuJoCo's composition
    of a chain of hinges), middle angle in [-pi/2, pi/2].

    Args:
        q: [..., 4] wxyz unit quaternions.
        axes: the hinge axes in chain order, e.g. (1, 0, 2) for y, x, z.

    Returns:
        [..., 3] angles in that order.
    """
    if tuple(axes) == (0, 1, 2):
        return rot.euler_xyz_from_quat(q)
    if sorted(axes) != [0, 1, 2]:
        raise ValueError(f"three distinct hinge axes are needed, got {tuple(axes)}")
    from scipy.spatial.transform import Rotation

    flat = np.asarray(q, np.float64).reshape(-1, 4)[:, [1, 2, 3, 0]]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", UserWarning)  # gimbal lock: scipy sets the third angle to 0
        e = Rotation.from_quat(flat).as_euler("".join("XYZ"[a] for a in axes))
    return e.reshape(np.shape(q)[:-1] + (3,))


def euler_branches(q: np.ndarray, axes: Sequence[int] = (0, 1, 2)) -> np.ndarray:
    """Both Euler solutions of rotations for hinges about ``axes`` (in chain order).

    Args:
        q: [..., 4] wxyz unit quaternions.
        axes: three distinct axis indices.

    Returns:
        [..., 2, 3]: (a, b, c) with b in [-pi/2, pi/2], and (a + pi, pi - b, c + pi).
    """
    e = euler_from_quat(q, axes)
    alt = np.stack([e[..., 0] + np.pi, np.pi - e[..., 1], e[..., 2] + np.pi], axis=-1)
    return np.stack([e, alt], axis=-2)


def viterbi_branch(cands: np.ndarray, lo: np.ndarray, hi: np.ndarray) -> np.ndarray:
    """Picks one candidate per frame: min sum of range violation + wrapped joint-space travel.

    Args:
        cands: [T, B, K, n] K candidate angle vectors per frame for B independent bodies.
        lo: [B, n] lower joint limits.
        hi: [B, n] upper joint limits.

    Returns:
        [T, B] int index of the chosen candidate.
    """
    T, B, K, _ = cands.shape
    unary = range_violation(cands, lo[:, None], hi[:, None]).sum(-1)  # [T, B, K]
    step = rot.wrap_angle(cands[1:, :, None, :, :] - cands[:-1, :, :, None, :])
    pair = np.abs(step).sum(-1)  # [T-1, B, Kprev, K]
    cost = unary[0]
    back = np.empty((T - 1, B, K), np.int64)
    for t in range(T - 1):
        tot = cost[:, :, None] + pair[t]  # [B, Kprev, K]
        back[t] = np.argmin(tot, axis=1)
        cost = np.take_along_axis(tot, back[t][:, None, :], axis=1)[:, 0] + unary[t + 1]
    path = np.empty((T, B), np.int64)
    path[-1] = np.argmin(cost, axis=-1)
    for t in range(T - 2, -1, -1):
        path[t] = np.take_along_axis(back[t], path[t + 1][:, None], axis=1)[:, 0]
    return path


def local_quats_to_dof(ch: Character, local_quat: np.ndarray, fit_ranges: bool = True) -> np.ndarray:
    """Hinge angles from local body rotations (see the module docstring).

    Args:
        ch: the character.
        local_quat: [T, nb, 4] wxyz rotation of each body relative to its parent (root ignored).
        fit_ranges: choose among equivalent solutions to respect the joint ranges; False gives the
            plain decomposition (a, c in (-pi, pi], b in [-pi/2, pi/2]).

    Returns:
        [T, n_dof] hinge angles; bodies without hinges are ignored.
    """
    T = local_quat.shape[0]
    lo, hi = ch.joint_range[:, 0], ch.joint_range[:, 1]
    dof = np.zeros((T, ch.num_dof))
    triples = []
    for b in range(1, ch.num_bodies):
        idx = ch.body_joints(b)
        axes = [ch.joint_axis[i] for i in idx]
        if len(idx) == 3 and sorted(axes) == [0, 1, 2]:
            triples.append((b, idx, axes))
        elif len(idx) == 1:
            a = rot.twist_angle(local_quat[:, b], axes[0])
            dof[:, idx[0]] = range_wrap(a, lo[idx[0]], hi[idx[0]]) if fit_ranges else a
        elif idx:
            raise NotImplementedError(f"body {ch.body_names[b]} has hinges on axes {axes}")
    if triples:
        idx = np.array([i for _, i, _ in triples])  # [B, 3]
        cands = np.stack([euler_branches(local_quat[:, b], ax) for b, _, ax in triples], 1)  # [T, B, 2, 3]
        if fit_ranges:
            cands = range_wrap(cands, lo[idx][:, None], hi[idx][:, None])
            choice = viterbi_branch(cands, lo[idx], hi[idx])
        else:
            choice = np.zeros((T, len(triples)), np.int64)
        chosen = np.take_along_axis(cands, choice[:, :, None, None], axis=2)[:, :, 0]
        dof[:, idx.reshape(-1)] = chosen.reshape(T, -1)
    return dof


def reference_body_pos(
    parents: Sequence[int], offsets: np.ndarray, root_pos: np.ndarray, local_quat: np.ndarray
) -> np.ndarray:
    """Body positions composed directly from local rotations along the parent chain (numpy).

    This is the independent check of MuJoCo FK (``Clip.fk_error_m``).

    Args:
        parents: [nb] parent index (-1 for the root; parents come before children).
        offsets: [nb, 3] body origin in its parent's frame.
        root_pos: [T, 3].
        local_quat: [T, nb, 4] wxyz (index 0 = root world rotation).

    Returns:
        [T, nb, 3] world positions.
    """
    T, nb = local_quat.shape[:2]
    pos = np.empty((T, nb, 3))
    quat = np.empty((T, nb, 4))
    pos[:, 0], quat[:, 0] = root_pos, local_quat[:, 0]
    for b in range(1, nb):
        p = parents[b]
        pos[:, b] = pos[:, p] + rot.quat_rotate(quat[:, p], np.broadcast_to(offsets[b], (T, 3)))
        quat[:, b] = rot.quat_mul(quat[:, p], local_quat[:, b])
    return pos
