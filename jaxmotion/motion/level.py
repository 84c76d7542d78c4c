"""Level a reference that stands on uneven feet.

A clip retargeted from another skeleton can stand with one foot above the floor and the other
inside it. The shared ``squat.json`` on our humanoid: the right sole 2-5 cm above the floor and
the left 0-3.4 cm below, in every frame. A lower-body discriminator in the heading frame sees that
height difference; on a flat floor the simulated character can only show it by standing on one
leg in a deep squat.

``level_feet`` tilts the whole body, per frame in which both feet are planted, about a horizontal
axis through the root, perpendicular to the line between the soles, until both soles are at the
same height, and then moves it vertically so that they rest on the floor. The joint angles are
not touched (beyond the clamp to the joint ranges), so every group's view relative to a link of
the body is unchanged; only the root's orientation and height differ. Frames with a foot lifted
(a step, a jump) are left as they are.
"""

from __future__ import annotations

import mujoco
import numpy as np

from jaxmotion.motion import rotations as rot
from jaxmotion.motion.clip import Clip, _model, build_clip
from jaxmotion.physics.character import character

FEET = ("right_foot", "left_foot")


def _lowest_points(m: mujoco.MjModel, d: mujoco.MjData, geoms: list[int]) -> np.ndarray:
    """[3] the lowest point of a set of spheres, capsules and boxes (already posed in ``d``)."""
    best = None
    for g in geoms:
        c, R, s = d.geom_xpos[g], d.geom_xmat[g].reshape(3, 3), m.geom_size[g]
        t = m.geom_type[g]
        if t == mujoco.mjtGeom.mjGEOM_SPHERE:
            drop = np.array([0.0, 0.0, s[0]])
        elif t == mujoco.mjtGeom.mjGEOM_CAPSULE:
            axis = R[:, 2] * s[1]
            drop = np.array([0.0, 0.0, s[0]]) + (axis if axis[2] > 0 else -axis)
        elif t == mujoco.mjtGeom.mjGEOM_BOX:
            drop = R @ (np.sign(R[2]) * s[:3])  # the corner with the lowest z
        else:
            continue
        p = c - drop
        if best is None or p[2] < best[2]:
            best = p
    if best is None:
        raise ValueError("the feet have no sphere, capsule or box geoms")
    return best


def sole_points(clip: Clip, qpos: np.ndarray | None = None) -> np.ndarray:
    """[T, 2, 3] the lowest point of the right and the left foot in each frame."""
    m = _model(clip.sword_shield)
    d = mujoco.MjData(m)
    geoms = []
    for name in FEET:
        b = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_BODY, name)
        if b < 0:
            raise ValueError(f"the character has no body {name!r} to level the feet with")
        geoms.append([g for g in range(m.ngeom) if m.geom_bodyid[g] == b])
    qpos = clip.qpos if qpos is None else qpos
    out = np.empty((qpos.shape[0], 2, 3))
    for t in range(qpos.shape[0]):
        d.qpos[:] = qpos[t]
        mujoco.mj_kinematics(m, d)
        out[t] = [_lowest_points(m, d, g) for g in geoms]
    return out


def _axis_angle_quat(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """[T, 4] wxyz rotations by ``angle`` [T] about unit ``axis`` [T, 3]."""
    h = 0.5 * angle[:, None]
    return np.concatenate([np.cos(h), np.sin(h) * axis], -1)


def level_feet(clip: Clip, planted: float = 0.1, iterations: int = 4, within_limits: bool = True) -> Clip:
    """The clip with both soles on the floor in every frame where both are within ``planted`` m
    of it (see the module docstring). ``iterations`` Newton steps of the tilt (each one exact to
    first order; four reach well below a millimetre). ``within_limits`` first clamps the joint
    angles to the character's ranges, as the environment does to every reference pose
    (``EnvConfig.ref_within_limits``); levelled before the clamp, the feet would part again."""
    qpos = clip.qpos.copy()
    if within_limits:
        rng = character(clip.sword_shield).joint_range
        qpos[:, 7:] = np.clip(qpos[:, 7:], rng[:, 0], rng[:, 1])
    soles = sole_points(clip, qpos)
    mask = np.all(soles[:, :, 2] < planted, axis=1)
    for _ in range(iterations if mask.any() else 0):
        d = soles[:, 0] - soles[:, 1]
        sep = np.maximum(np.linalg.norm(d[:, :2], axis=-1), 1e-3)
        # Turning by theta about a = (d_y, -d_x, 0) / sep raises the right sole by theta * sep
        # relative to the left one.
        axis = np.stack([d[:, 1], -d[:, 0], 0 * sep], -1) / sep[:, None]
        theta = np.where(mask, -d[:, 2] / sep, 0.0)
        qpos[:, 3:7] = rot.quat_mul(_axis_angle_quat(axis, theta), qpos[:, 3:7])
        soles = sole_points(clip, qpos)
    lift = np.where(mask, -soles[:, :, 2].mean(1), 0.0)
    qpos[:, 2] += lift
    return build_clip(
        name=clip.name,
        path=clip.path,
        format=clip.format,
        fps=clip.fps,
        loop=clip.loop,
        sword_shield=clip.sword_shield,
        root_pos=qpos[:, :3],
        root_quat=qpos[:, 3:7],
        dof_pos=qpos[:, 7:],
        fk_error_m=clip.fk_error_m,
    )
