"""Observation functions shared by the simulation side and the reference (MotionLib) side.

Both sides describe the character by the world-frame state of its links, so one function turns
either into the policy's or a discriminator's observation: a discriminator then sees
``(s_t, s_{t+1})`` from the simulator exactly as it sees the same window cut from a clip.
Pure jnp; no MJX here.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct

from jaxmotion.motion import rotations as R


@struct.dataclass
class LinkFrames:
    """World-frame state of every link; any leading axes (history, batch).

    Attributes:
      pos: [..., nb, 3] link origins (m).
      quat: [..., nb, 4] link orientations, wxyz.
      lin_vel: [..., nb, 3] linear velocities of the link origins (m/s).
      ang_vel: [..., nb, 3] angular velocities (rad/s), world frame.
    """

    pos: jax.Array
    quat: jax.Array
    lin_vel: jax.Array
    ang_vel: jax.Array


def heading_frame(root_pos: jax.Array, root_quat: jax.Array) -> tuple[jax.Array, jax.Array]:
    """The character's heading frame: yaw-only rotation, origin = root projected to the floor.

    Args:
      root_pos: [..., 3]; root_quat: [..., 4] wxyz.
    Returns:
      (origin [..., 3] with z = 0, inverse heading quaternion [..., 4]).
    """
    origin = root_pos * jnp.array([1.0, 1.0, 0.0], root_pos.dtype)
    return origin, R.heading_inv(root_quat)


def _to_frame(pos, quat, origin, inv_q):
    """Expresses positions [.., L, 3] and orientations [.., L, 4] in a frame (origin, inv rot)."""
    inv_l = inv_q[..., None, :]
    p = R.quat_rotate(jnp.broadcast_to(inv_l, pos.shape[:-1] + (4,)), pos - origin[..., None, :])
    q = R.quat_mul(jnp.broadcast_to(inv_l, quat.shape), quat)
    return p, q


def policy_obs(hist: LinkFrames) -> jax.Array:
    """Policy observation from a history of link states, in the newest frame's heading frame.

    Args:
      hist: LinkFrames with leading [H, nb] (oldest first); the last frame is the current one.
    Returns:
      [H * nb * 15]: per frame and link, position (3, height kept absolute), orientation as
      tangent-normal (6), linear and angular velocity (3 + 3).
    """
    origin, inv_q = heading_frame(hist.pos[-1, 0], hist.quat[-1, 0])
    p, q = _to_frame(hist.pos, hist.quat, origin, inv_q)
    rot = lambda v: R.quat_rotate(jnp.broadcast_to(inv_q, v.shape[:-1] + (4,)), v)
    feats = jnp.concatenate([p, R.quat_to_tan_norm(q), rot(hist.lin_vel), rot(hist.ang_vel)], -1)
    return feats.reshape(-1)


def disc_obs(pos: jax.Array, quat: jax.Array, links: jax.Array, anchor: int) -> jax.Array:
    """A body group's discriminator observation over a window of frames.

    With an anchor link, each frame's group links are expressed in that frame's anchor frame
    (position relative to the anchor, full inverse rotation of the anchor). Without one
    (``anchor < 0``), all frames are expressed in the heading frame of the newest frame, so the
    window keeps the root's motion.

    Args:
      pos: [F, nb, 3], quat: [F, nb, 4] wxyz, oldest first.
      links: [L] int link indices (static). anchor: link index, or -1 for the heading frame.
    Returns:
      [F * L * 9]: per frame and link, position (3) and tangent-normal orientation (6).
    """
    if anchor >= 0:
        origin = pos[:, anchor]
        inv_q = R.quat_conj(quat[:, anchor])
    else:
        o, iq = heading_frame(pos[-1, 0], quat[-1, 0])
        origin = jnp.broadcast_to(o, pos[:, 0].shape)
        inv_q = jnp.broadcast_to(iq, quat[:, 0].shape)
    p, q = _to_frame(pos[:, links], quat[:, links], origin, inv_q)
    return jnp.concatenate([p, R.quat_to_tan_norm(q)], -1).reshape(-1)
