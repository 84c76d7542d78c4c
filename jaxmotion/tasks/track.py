"""Motion tracking: follow a reference clip frame by frame (Perpetual Humanoid Control, Luo et al. 2023).

The scene's init clips are the clips to track (``EnvConfig.init_motions``); each episode starts
by reference-state initialisation at a random time of a random clip (the env's reset) and the
goal is that clip's next frame. Notes ``phc.md`` §1-§3, the authors' code where it differs:

* **Goal features**, all in the simulated root's heading frame, per body: the position
  difference reference - simulation (3), the rotation difference ``q_ref * q_sim^-1`` as 6D (6),
  the linear and angular velocity differences (3 + 3), the reference position relative to the
  simulated root (3) and the reference rotation (6D, 6): 24 per body (``goal="rotation"``,
  15 x 24 = 360 for our humanoid); ``goal="keypoint"`` keeps the position and velocity ones (9).
* **Reward** (one objective, ``imitation``): ``sum_k w_k exp(-c_k * e_k)`` over the mean squared
  position error (c = 100, w = 0.5), rotation angle (10, 0.3), linear (0.1, 0.1) and angular
  velocity errors (0.1, 0.1) of all bodies: 1 for a perfect frame; minus the energy penalty
  ``energy_coef * sum_j |tau_j qdot_j|`` (the code's linear power, from the servo's torque at the
  new state; the scene reports 0 on an episode's first 3 steps).
* **Termination**: any body except the feet farther than 0.25 m from its reference (the code's
  ``max`` rule), or their mean beyond ``termination_distance`` (``mean``, the paper's 0.5 m). A
  clip that ends truncates the episode (bootstrapped), a loop clip too (its wrap would move the
  reference root back to the cycle's start).

With ``track.recovery.enabled`` the tracker also learns fail-state recovery: starts from the
ground and from far away, the point goal while far, recovery episodes (``tasks/recovery.py``).

Reference link frames come from the forward kinematics of the interpolated joint angles and
velocities (``env.frames_of``), so a perfect tracker matches them to float precision.
"""

from __future__ import annotations

import dataclasses
from typing import Annotated, Any, Literal

import jax
import jax.numpy as jnp
from flax import struct

from jaxmotion.config.checks import Min, NonNegative, Positive
from jaxmotion.motion import observations as O
from jaxmotion.motion import rotations as R
from jaxmotion.motion.motionlib import qpos_qvel, sample
from jaxmotion.tasks import recovery as RC
from jaxmotion.tasks.base import Task, TaskStep


@dataclasses.dataclass(frozen=True)
class TrackConfig:
    """Motion tracking (Perpetual Humanoid Control; notes phc.md §0-§3): follow the init clips
    frame by frame. Defaults: the authors' code."""

    goal: Literal["rotation", "keypoint"] = "rotation"
    """'rotation' (24 features per body) or 'keypoint' (positions and velocities only, 9)."""
    termination: Literal["max", "mean"] = "max"
    """'max': any body but the feet farther than ``termination_distance`` from its reference
    (the code, 0.25 m); 'mean': the mean over those bodies (the paper, 0.5 m)."""
    termination_distance: Positive = 0.25
    exponents: Annotated[tuple[float, float, float, float], Min(0)] = (100.0, 10.0, 0.1, 0.1)
    """k of exp(-k * mean squared error) for position, rotation angle, linear and angular velocity."""
    term_weights: Annotated[tuple[float, float, float, float], Min(0)] = (0.5, 0.3, 0.1, 0.1)
    """Weights of those four terms (they sum to 1: a perfect frame pays 1)."""
    weight: NonNegative = 0.5
    """ω of the imitation objective (the paper's 0.5 task / 0.5 motion prior)."""
    residual: bool = False
    """False: the PD target is the joint range's mid-point + the action (the authors' code).
    True: it is the reference's joint angles one control step ahead (clamped to the joint ranges)
    + the action, so an untrained policy already servos towards the clip and learning only has
    to add the corrections that keep it balanced."""
    energy_coef: NonNegative = 0.0005
    """The energy penalty -c * sum_j |tau_j qdot_j| (linear mechanical power, the authors' code;
    the paper prints the square) added to the imitation reward (the scene reports no power on an
    episode's first 3 steps); 0 disables it."""
    recovery: RC.RecoveryConfig = RC.RecoveryConfig()
    """Fail-state recovery (``tasks/recovery.py``): off by default."""


@struct.dataclass
class TrackGoal:
    clip: jax.Array  # int32: the clip being tracked
    time: jax.Array  # reference time (s) of the character's current frame
    rec: Any = None  # RecoveryState with recovery enabled (None keeps older run folders' layout)


class Track(Task):
    """Track the init clips (see the module docstring)."""

    settings = (("track", TrackConfig),)

    evaluator = "tracking"
    mines_clips = True

    reward_names = ("imitation",)

    def __init__(self, cfg, env):
        super().__init__(cfg, env)
        c = cfg.track
        if c.goal not in ("rotation", "keypoint"):
            raise ValueError(f"track.goal must be 'rotation' or 'keypoint', got {c.goal!r}")
        if c.termination not in ("max", "mean"):
            raise ValueError(f"track.termination must be 'max' or 'mean', got {c.termination!r}")
        ch = env.character
        feet = {ch.body_index(b) for b in env.cfg.allowed_contacts}
        self._checked = jnp.asarray([b for b in range(ch.num_bodies) if b not in feet], jnp.int32)
        self.goal_parts = (("track", ch.num_bodies * (24 if c.goal == "rotation" else 9)),)
        self._pool = None
        if c.recovery.enabled:
            from jaxmotion.physics.falls import fallen_states

            pool = fallen_states(
                env.cfg.physics, c.recovery.pool_size, c.recovery.pool_seed, scale=env.cfg.action_scale
            )
            self._pool = jnp.asarray(pool)

    @property
    def recovering(self) -> bool:
        return self.cfg.track.recovery.enabled

    def weights(self):
        return (self.cfg.track.weight,)

    def ahead(self, goal: TrackGoal, dt: float) -> jax.Array:
        """How far the reference clock moves in ``dt``: not at all while a recovery freezes it."""
        if goal.rec is None:
            return jnp.asarray(dt, jnp.float32)
        return jnp.where(goal.rec.frozen & (goal.rec.grace > 0), 0.0, dt)

    def reference(self, goal: TrackGoal, dt_ahead: float) -> O.LinkFrames:
        """The tracked clip's link frames ``dt_ahead`` seconds of its clock after the current frame."""
        return self.env.frames_of(*self.reference_coords(goal, dt_ahead))

    def reference_coords(self, goal: TrackGoal, dt_ahead: float) -> tuple[jax.Array, jax.Array]:
        """(qpos [nq], qvel [nv]) of the tracked clip ``dt_ahead`` seconds of its clock after the
        current frame: what ``reference`` makes link frames of."""
        return qpos_qvel(sample(self.env.init_lib, goal.clip, goal.time + self.ahead(goal, dt_ahead)))

    def pd_base(self, goal: TrackGoal) -> jax.Array | None:
        """With ``residual``: the reference's joint angles one control step ahead, within limits."""
        if not self.cfg.track.residual:
            return None
        dof = sample(self.env.init_lib, goal.clip, goal.time + self.ahead(goal, self.env.dt)).dof_pos
        return self.env.clip_dof(dof)

    def start_pose(self, rng, qpos_h, qvel_h, start):
        """With recovery: fallen and far starts (``recovery.recovery_starts``); the start kind
        joins ``start`` for ``init``."""
        if not self.recovering:
            return qpos_h, qvel_h, start
        qpos_h, qvel_h, kind = RC.recovery_starts(rng, qpos_h, qvel_h, self._pool, self.cfg.track.recovery)
        return qpos_h, qvel_h, (*start, kind)

    def init(self, rng, frame, start=None):
        if start is None:
            raise ValueError("the track task needs the reset's clip and time (env.reset passes them)")
        goal = TrackGoal(clip=jnp.asarray(start[0], jnp.int32), time=jnp.asarray(start[1], jnp.float32))
        if not self.recovering:
            return goal
        kind = jnp.asarray(start[2] if len(start) > 2 else 0, jnp.int32)
        dist = RC.root_distance(self.reference(goal, 0.0), frame)
        grace = jnp.where(kind > 0, self.cfg.track.recovery.recovery_steps, 0).astype(jnp.int32)
        frozen = (kind & RC.FALLEN) > 0
        return goal.replace(rec=RC.RecoveryState(grace=grace, frozen=frozen, dist=dist))

    def observe(self, goal: TrackGoal, frame: O.LinkFrames) -> jax.Array:
        return self.features(self.reference(goal, self.env.dt), frame)

    def features(self, ref: O.LinkFrames, frame: O.LinkFrames) -> jax.Array:
        """The goal features of the reference's next frame ``ref`` seen from the simulated ``frame``
        (the exported policies compute them from a reference given as generalised coordinates)."""
        if self.recovering and self.cfg.track.recovery.point_goal:
            ref = RC.far_goal(ref, frame, self.cfg.track.recovery)
        _, inv = O.heading_frame(frame.pos[0], frame.quat[0])
        rot = lambda v: R.quat_rotate(jnp.broadcast_to(inv, v.shape[:-1] + (4,)), v)
        dp = rot(ref.pos - frame.pos)
        dv, dw = rot(ref.lin_vel - frame.lin_vel), rot(ref.ang_vel - frame.ang_vel)
        rel = rot(ref.pos - frame.pos[0])
        if self.cfg.track.goal == "keypoint":
            return jnp.concatenate([dp, dv, rel], -1).reshape(-1)
        inv_b = jnp.broadcast_to(inv, ref.quat.shape)
        dq = R.quat_mul(R.quat_mul(inv_b, R.quat_mul(ref.quat, R.quat_conj(frame.quat))), R.quat_conj(inv_b))
        ref_q = R.quat_mul(inv_b, ref.quat)
        return jnp.concatenate([dp, R.quat_to_tan_norm(dq), dv, dw, rel, R.quat_to_tan_norm(ref_q)], -1).reshape(-1)

    def errors(self, ref: O.LinkFrames, frame: O.LinkFrames) -> dict[str, jax.Array]:
        """Per-body position error (m) and the four mean squared errors of the reward."""
        body = jnp.linalg.norm(ref.pos - frame.pos, axis=-1)
        return {
            "body": body,
            "pos": jnp.mean(jnp.square(ref.pos - frame.pos)),
            "rot": jnp.mean(jnp.square(R.quat_angle_between(frame.quat, ref.quat))),
            "vel": jnp.mean(jnp.square(ref.lin_vel - frame.lin_vel)),
            "ang": jnp.mean(jnp.square(ref.ang_vel - frame.ang_vel)),
        }

    def imitation_reward(self, e: dict[str, jax.Array]) -> jax.Array:
        c = self.cfg.track
        terms = jnp.stack([e["pos"], e["rot"], e["vel"], e["ang"]])
        return jnp.sum(jnp.asarray(c.term_weights) * jnp.exp(-jnp.asarray(c.exponents) * terms))

    def step(self, goal: TrackGoal, prev, frame, rng, power=None) -> TaskStep:
        c, dt = self.cfg.track, self.env.dt
        ref = self.reference(goal, dt)
        e = self.errors(ref, frame)
        checked = e["body"][self._checked]
        far = jnp.max(checked) if c.termination == "max" else jnp.mean(checked)
        lib = self.env.init_lib
        t = goal.time + self.ahead(goal, dt)
        # The clip ends when it has no next frame to track, loop clips too: ``sample`` wraps a
        # loop's time without carrying its root forward, so past the end the reference would jump
        # back to the cycle's start and every episode there would end as a failure.
        ended = t + dt > lib.clip_duration[goal.clip] + 1e-6
        info = {"body_error_m": jnp.mean(e["body"]), "max_error_m": jnp.max(checked)}
        reward = self.imitation_reward(e)
        terminated = far > c.termination_distance
        goal = goal.replace(time=t)
        if self.recovering:
            reward, terminated, goal = self._recovery_step(goal, ref, frame, reward, terminated, rng, info)
        if c.energy_coef and power is not None:
            info["energy"] = c.energy_coef * power
            reward = reward - info["energy"]
        return TaskStep(goal=goal, rewards=reward[None], terminated=terminated, info=info, truncated=ended)

    def _recovery_step(self, goal: TrackGoal, ref, frame, imitation, would_end, rng, info):
        """(reward, terminated, goal) with recovery: the point-goal reward, no termination while
        a recovery's grace lasts, and an episode the rule would end going on as a recovery
        episode with probability ``recovery_prob`` (``tasks/recovery.py``)."""
        rc, rec = self.cfg.track.recovery, goal.rec
        dist = RC.root_distance(ref, frame)
        reward = RC.recovery_reward(rec.dist, dist, imitation, rc)
        in_grace = rec.grace > 0
        again = would_end & ~in_grace & (jax.random.uniform(rng) < rc.recovery_prob)
        grace = jnp.where(again, rc.recovery_steps, jnp.maximum(rec.grace - 1, 0)).astype(jnp.int32)
        frozen = again | (rec.frozen & (grace > 0))
        info["root_distance_m"] = dist
        info["recovering"] = (in_grace | again).astype(jnp.float32)
        rec = RC.RecoveryState(grace=grace, frozen=frozen, dist=dist)
        return reward, would_end & ~in_grace & ~again, goal.replace(rec=rec)

    def summary(self, info, alive):
        if not alive.any():
            return {"body_error_m": float("nan"), "max_error_m": float("nan")}
        return {
            "body_error_m": float(info["body_error_m"][alive].mean()),
            "max_error_m": float(info["max_error_m"][alive].mean()),
        }
