"""A run's reference motion as the evaluators and viewers see it: a group's first clip at the
control rate, and the rigid xy + yaw alignment that places a reference on the simulated character.

Shared by evaluation (DTW errors) and visualisation (the ghost in videos and replays); it needs an
env (``learner.env`` of any learner) and nothing above it.
"""

from __future__ import annotations

import jax.numpy as jnp
import numpy as np

from jaxmotion.motion import observations as O
from jaxmotion.motion import rotations as R
from jaxmotion.motion.motionlib import MotionState, sample


def group_frame_positions(pos: np.ndarray, quat: np.ndarray, links: np.ndarray, anchor: int) -> np.ndarray:
    """[T, L, 3] link positions in each frame's own group frame (anchor link or heading frame)."""
    if anchor >= 0:
        origin, inv_q = pos[:, anchor], R.quat_conj(quat[:, anchor])
    else:
        origin, inv_q = O.heading_frame(pos[:, 0], quat[:, 0])
        origin, inv_q = np.asarray(origin), np.asarray(inv_q)
    rel = pos[:, links] - origin[:, None]
    return np.asarray(R.quat_rotate(np.broadcast_to(inv_q[:, None], rel.shape[:-1] + (4,)), rel))


def align_to_start(
    ref_root_pos: np.ndarray, ref_root_quat: np.ndarray, sim_root_pos0: np.ndarray, sim_root_quat0: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The rigid xy + yaw motion taking the reference's first root heading frame onto the
    simulation's first one: ``(q_align [4] wxyz, offset [3])`` with
    ``p' = rotate(q_align, p) + offset``.

    Args:
      ref_root_pos: [T, 3], ref_root_quat: [T, 4] (only frame 0 is used).
      sim_root_pos0: [3], sim_root_quat0: [4].
    """
    f32 = lambda x: np.asarray(x, np.float32)  # heading_frame is jnp (float32 without x64)
    o_ref, inv_ref = (np.asarray(x, np.float64) for x in O.heading_frame(f32(ref_root_pos[0]), f32(ref_root_quat[0])))
    o_sim, inv_sim = (np.asarray(x, np.float64) for x in O.heading_frame(f32(sim_root_pos0), f32(sim_root_quat0)))
    q = np.asarray(R.quat_mul(R.quat_conj(inv_sim), inv_ref))  # ref heading frame -> sim's
    return q, o_sim - np.asarray(R.quat_rotate(q, o_ref))


def align_pose(
    q_align: np.ndarray, offset: np.ndarray, pos: np.ndarray, quat: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Applies ``align_to_start``'s motion to positions [..., 3] and orientations [..., 4]."""
    pos, quat = np.asarray(pos, np.float64), np.asarray(quat, np.float64)
    p = np.asarray(R.quat_rotate(np.broadcast_to(q_align, pos.shape[:-1] + (4,)), pos)) + offset
    q = np.asarray(R.quat_mul(np.broadcast_to(q_align, quat.shape), quat))
    return p, q


def world_aligned(ref_pos: np.ndarray, ref_quat: np.ndarray, sim_pos0: np.ndarray, sim_quat0: np.ndarray) -> np.ndarray:
    """Reference positions [T, nb, 3] moved rigidly (xy + yaw) onto the simulation's first root frame."""
    q, off = align_to_start(ref_pos[:, 0], ref_quat[:, 0], sim_pos0[0], sim_quat0[0])
    return align_pose(q, off, ref_pos, ref_quat)[0]


def reference_state(learner, group: int, num_frames: int) -> MotionState:
    """The group's first clip at the control rate, repeated to ``num_frames`` frames."""
    lib = learner.env.motion_libs[group]
    dur = float(lib.clip_duration[0])
    t = (np.arange(num_frames) * learner.env.dt) % max(dur, 1e-6)
    return sample(lib, jnp.zeros(num_frames, jnp.int32), jnp.asarray(t, jnp.float32))


def reference_sequence(learner, group: int, num_frames: int) -> tuple[np.ndarray, np.ndarray]:
    """``reference_state``'s link positions [T, nb, 3] and orientations [T, nb, 4]."""
    ms = reference_state(learner, group, num_frames)
    return np.asarray(ms.body_pos), np.asarray(ms.body_quat)
