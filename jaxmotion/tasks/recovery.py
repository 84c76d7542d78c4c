"""Fail-state recovery for the tracker (PHC §3.2, Eqs. 3-4; notes phc.md §0 and §4).

A tracker with ``track.recovery.enabled`` learns to get back to its reference from the ground
and from far away, and then to track again. What changes, as the authors' code does it:

* **The fail-state goal** (``far_goal``): while the simulated root is farther than
  ``close_distance`` (0.25 m) from the reference root, every non-root reference body takes the
  simulated body's position and rotation and every reference velocity the simulated one, so the
  goal features reduce to where the root should be and how it should be turned (a point goal);
  beyond ``far_distance`` (3 m) the root target is pulled onto that radius (a direction).
* **The reward** (``recovery_reward``): ``9 min(d_{t-1} - d_t, 1/3)`` for closing the root
  distance d, plus half the imitation reward while d <= ``close_distance``, minus the energy
  penalty (the paper's Eq. 4 weights the point goal and imitation differently; the code's form).
* **Starts** (``Track.start_pose``): a reset starts, with probability ``fall_prob``, from a
  fallen state (``physics/falls.py``: the authors' drop-and-flail pool) under the reference
  root, the reference clock frozen for ``recovery_steps``; and, independently with probability
  ``far_prob``, moved by a random offset of ``far_start`` metres (uniform over that annulus;
  the reference keeps playing unless the start is also fallen). Neither terminates for
  ``recovery_steps`` control steps (90: 3 s at 30 Hz).
* **Recovery episodes**: an episode that the distance rule would end continues instead, with
  probability ``recovery_prob``, as a recovery episode (no termination and a frozen reference
  clock for ``recovery_steps``): the falls the tracker makes itself are the material it learns
  to get up from.

Departure: the authors' schedule (every reset a fall and the motion prior alone for the first
epochs of the recovery phase) is not reproduced; the recovery primitive starts from a trained
tracker instead (``init_from``).
"""

from __future__ import annotations

import dataclasses
from typing import Annotated

import jax
import jax.numpy as jnp
from flax import struct

from jaxmotion.config.checks import Min, Ordered, Positive, Range
from jaxmotion.motion import observations as O

POINT_SCALE = 9.0
POINT_CAP = 1.0 / 3.0
"""The point-goal reward ``POINT_SCALE * min(d_{t-1} - d_t, POINT_CAP)`` (the authors' constants)."""


@dataclasses.dataclass(frozen=True)
class RecoveryConfig:
    """Fail-state recovery (``tasks/recovery.py``). Defaults: the authors' code (notes phc.md §4)."""

    enabled: bool = False
    """The fail-state goal, the point-goal reward and the recovery starts below."""
    point_goal: bool = True
    """The fail-state goal features; False keeps the tracker's own features even when far (what
    a tracker trained without recovery sees: the recovery evaluation's baseline)."""
    close_distance: Positive = 0.25
    """Root distance (m) within which the goal and reward are the tracker's; beyond it, the point goal."""
    far_distance: Positive = 3.0
    """A root target farther than this (m) is pulled onto this radius."""
    far_start: Annotated[tuple[float, float], Min(0), Ordered()] = (0.0, 5.0)
    """Radius range (m) of a far start's offset, uniform over the annulus (the authors: a 5-m disk)."""
    far_prob: Annotated[float, Range(0, 1)] = 1.0
    """Fraction of reference-state starts that are far starts (the authors: all)."""
    fall_prob: Annotated[float, Range(0, 1)] = 0.3
    """Fraction of starts from a fallen state."""
    recovery_prob: Annotated[float, Range(0, 1)] = 0.5
    """Probability that an episode the distance rule would end goes on as a recovery episode."""
    recovery_steps: Annotated[int, Min(1)] = 90
    """Control steps without termination after a fallen or far start or a recovery episode's start."""
    pool_size: Annotated[int, Min(1)] = 256
    """Fallen states in the pool (made once per process, ``physics/falls.py``)."""
    pool_seed: int = 0


@struct.dataclass
class RecoveryState:
    grace: jax.Array  # int32: control steps left without termination
    frozen: jax.Array  # bool: the reference clock stands still while grace lasts
    dist: jax.Array  # root distance to the reference root (m) after the last step


FALLEN, FAR = 1, 2
"""Bits of the start kind ``Track.start_pose`` passes on to ``Track.init`` (0: a plain
reference-state start)."""


def far_goal(ref: O.LinkFrames, frame: O.LinkFrames, c: RecoveryConfig) -> O.LinkFrames:
    """The reference the goal features are computed from (the fail-state goal, see the module)."""
    delta = ref.pos[0] - frame.pos[0]
    d = jnp.linalg.norm(delta)
    far = d > c.close_distance
    keep_root = lambda r, s: jnp.where(far, s.at[0].set(r[0]), r)
    root = jnp.where(d > c.far_distance, frame.pos[0] + delta / jnp.maximum(d, 1e-6) * c.far_distance, ref.pos[0])
    return O.LinkFrames(
        pos=keep_root(ref.pos, frame.pos).at[0].set(root),
        quat=keep_root(ref.quat, frame.quat),
        lin_vel=jnp.where(far, frame.lin_vel, ref.lin_vel),
        ang_vel=jnp.where(far, frame.ang_vel, ref.ang_vel),
    )


def root_distance(ref: O.LinkFrames, frame: O.LinkFrames) -> jax.Array:
    return jnp.linalg.norm(ref.pos[0] - frame.pos[0])


def recovery_reward(prev_dist: jax.Array, dist: jax.Array, imitation: jax.Array, c: RecoveryConfig) -> jax.Array:
    """The point-goal reward for closing the root distance, plus half the imitation reward when close."""
    point = POINT_SCALE * jnp.minimum(prev_dist - dist, POINT_CAP)
    return point + jnp.where(dist <= c.close_distance, 0.5 * imitation, 0.0)


def far_offset(rng: jax.Array, c: RecoveryConfig) -> jax.Array:
    """[2] a far start's xy offset: radius uniform over the ``far_start`` annulus, any direction."""
    k_r, k_a = jax.random.split(rng)
    lo, hi = c.far_start
    r = jnp.sqrt(jax.random.uniform(k_r, (), minval=lo * lo, maxval=hi * hi))
    a = jax.random.uniform(k_a, (), minval=-jnp.pi, maxval=jnp.pi)
    return r * jnp.stack([jnp.cos(a), jnp.sin(a)])


def recovery_starts(
    rng: jax.Array, qpos_h: jax.Array, qvel_h: jax.Array, pool: jax.Array, c: RecoveryConfig
) -> tuple[jax.Array, jax.Array, jax.Array]:
    """(qpos_h, qvel_h, kind) of a reset's start window [H, nq]/[H, nv]: with probability
    ``fall_prob`` a fallen pose from ``pool`` [P, nq] under the reference root, at rest for the
    whole window (kind bit ``FALLEN``); independently, with probability ``far_prob``, moved by
    ``far_offset`` (bit ``FAR``); neither: the reference state itself (kind 0)."""
    k_fall, k_pick, k_far, k_off = jax.random.split(rng, 4)
    fallen = jax.random.uniform(k_fall) < c.fall_prob
    far = jax.random.uniform(k_far) < c.far_prob
    pose = pool[jax.random.randint(k_pick, (), 0, pool.shape[0])]
    pose = pose.at[:2].set(qpos_h[-1, :2])
    qpos_h = jnp.where(fallen, jnp.broadcast_to(pose, qpos_h.shape), qpos_h)
    qvel_h = jnp.where(fallen, 0.0, qvel_h)
    qpos_h = qpos_h.at[:, :2].add(jnp.where(far, far_offset(k_off, c), 0.0))
    kind = jnp.where(fallen, FALLEN, 0) + jnp.where(far, FAR, 0)
    return qpos_h, qvel_h, kind.astype(jnp.int32)
