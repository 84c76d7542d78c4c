"""What a task is: goal state, goal observation, named rewards, extra terminations, metrics.

A scene (``envs/humanoid.py``: the character, its physics and reference clips) runs one task. The
task is a set of pure functions of its own goal-state pytree and the character's link frames,
vmapped with the environment:

* ``init(rng, frame, start) -> goal``: a goal for a freshly reset character (``frame``: its link
  frames; ``start``: the clip and time of the reference state it was reset to);
* ``observe(goal, frame) -> [goal_size]``: the goal features, which the policy and critics get
  after the body-state features, raw (not normalised, as the authors' code);
* ``step(goal, prev, frame, rng, power) -> TaskStep``: after a control step from link frames
  ``prev`` to ``frame`` (``power``: the servo's mechanical power sum_j |tau_j qdot_j| at the new
  state, W; 0 on an episode's first 3 steps, while the servo takes over from the reference
  state, as the tracker's authors do): the next goal, one reward per ``reward_names`` entry, an extra termination and
  per-step ``info`` scalars that ``summary`` turns into the task's evaluation metrics;
* for a scene with props (free balls, ``physics/props.py``): ``sense(goal, props) -> goal``
  before ``step``, with the props' state and racket forces after the physics step, and
  ``place(goal, props) -> props`` after ``step`` and at reset, where the task wants them (a
  new ball); the scene writes that into the physics state.

The learner makes one objective (critic head, PopArt statistics, weight ω) per reward name, next
to one per discriminator; it never looks at which task it runs. Tasks are found by name in
``tasks.TASKS``, each with its settings beside it in its own module.
"""

from __future__ import annotations

from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from jaxmotion.motion.observations import LinkFrames
from jaxmotion.motion import rotations as R


@struct.dataclass
class TaskStep:
    """What a task reports for one control step (one environment)."""

    goal: Any
    rewards: jax.Array  # [len(reward_names)]
    terminated: jax.Array  # bool: the task ends the episode (no bootstrap)
    info: dict  # name -> scalar, for metrics
    truncated: Any = False  # bool: the task's time is up (e.g. the tracked clip ended; bootstrapped)


class Task:
    """The no-goal task: pure imitation (no goal features, no task rewards)."""

    reward_names: ClassVar[tuple[str, ...]] = ()
    settings: ClassVar[tuple[tuple[str, type], ...]] = ()
    """The task's settings: (field of ``TaskConfig``, frozen dataclass) pairs; tasks may share a
    field (aim+location reads ``location`` too). ``TaskConfig`` is assembled from these."""
    evaluator: ClassVar[str] = "imitation"
    mines_clips: ClassVar[bool] = False
    """Resets pick the clips it tracks, so hard-negative mining can reweight them."""
    """How `python -m jaxmotion.eval` evaluates a run of this task (a key of `evaluation.EVALUATORS`)."""
    min_reward: ClassVar[float] = 0.0
    """The lowest reward any of this task's objectives pays per step."""

    def __init__(self, cfg, env):
        """``cfg``: the scene's ``TaskConfig`` (its ``name`` and every registered task's settings)."""
        self.cfg = cfg
        self.env = env

    goal_parts: ClassVar[tuple[tuple[str, int], ...]] = ()
    """The goal features as named blocks (name, size), in observation order. A frozen meta
    policy (``training/meta.py``) finds its own goal blocks in a new task's goal by these names."""

    @property
    def goal_size(self) -> int:
        return sum(n for _, n in self.goal_parts)

    def weights(self) -> tuple[float, ...]:
        """ω of each reward, as configured."""
        return ()

    def start_pose(self, rng: jax.Array, qpos_h: jax.Array, qvel_h: jax.Array, start: tuple) -> tuple:
        """(qpos_h, qvel_h, start): the reset's start window ([H, nq], [H, nv], the reference
        state's, oldest first) and its ``start`` (clip, time), which a task may move or replace
        and extend for its ``init`` (the tracker's fallen and far starts). Default: unchanged."""
        return qpos_h, qvel_h, start

    def init(self, rng: jax.Array, frame: LinkFrames, start: tuple | None = None) -> Any:
        """``start``: (clip index, time in s) of the reference state the character was reset to,
        and whatever ``start_pose`` added."""
        return jnp.zeros((0,), jnp.float32)

    def observe(self, goal: Any, frame: LinkFrames) -> jax.Array:
        return jnp.zeros((0,), jnp.float32)

    def step(
        self, goal: Any, prev: LinkFrames, frame: LinkFrames, rng: jax.Array, power: jax.Array | None = None
    ) -> TaskStep:
        return TaskStep(goal=goal, rewards=jnp.zeros((0,), jnp.float32), terminated=jnp.zeros((), bool), info={})

    def pd_base(self, goal: Any) -> jax.Array | None:
        """The PD targets [n_dof] the action is added to (``HumanoidEnv.pd_target``: base +
        ``EnvConfig.action_scale`` * action * half-range), or None for the joint ranges' mid-points."""
        return None

    def sense(self, goal: Any, props) -> Any:
        """The goal after the physics step moved the scene's props (``physics/props.Props``)."""
        return goal

    def place(self, goal: Any, props):
        """Where the props should be before the next step (``Props``); default: where they are."""
        return props

    def summary(self, info: dict[str, np.ndarray], alive: np.ndarray) -> dict[str, float]:
        """Evaluation metrics from per-step ``info`` arrays [T, E] over steps where ``alive``."""
        return {}

    def steer(self, goal: Any, frame: LinkFrames, move: jax.Array, turn: jax.Array) -> Any:
        """Interactive control (``python -m jaxmotion.play``), applied before every step: the
        user moves the target by ``move`` [2] (world xy, m) and turns the goal direction by
        ``turn`` (rad, about z). A steered goal never expires on its own. Default: unchanged."""
        return goal

    def markers(self, goal: Any, frame: LinkFrames) -> dict[str, jax.Array]:
        """What the video draws of the goal: name -> [2, 3] world segment (from, to); a segment
        of zero length is a point (``render.py``: a sphere; otherwise an arrow)."""
        return {}


def combine_weights(group_weights: tuple[float | None, ...], goal_weights: tuple[float, ...]) -> np.ndarray:
    """ω of every objective, discriminators first (the authors' rule, notes §0.6).

    Goal weights are taken as given. Given discriminator weights are renormalised to sum to 1,
    or, when some are unassigned (None), the unassigned share ``1 - Σ given`` equally; all
    discriminator weights are then scaled by ``1 - Σ goal weights``.
    """
    goal = np.asarray(goal_weights, np.float64)
    if np.any(goal < 0) or (len(group_weights) and goal.sum() >= 1.0 - 1e-9):
        raise ValueError(
            f"goal weights {tuple(goal_weights)} must be non-negative and sum below 1 when there are discriminators"
        )
    given = [w for w in group_weights if w is not None]
    if any(w < 0 for w in given):
        raise ValueError(f"group weights must be non-negative, got {group_weights}")
    n_free = sum(w is None for w in group_weights)
    if n_free == 0:
        total = sum(given)
        disc = np.asarray(given, np.float64) / total if total > 0 else np.full(len(given), 1.0 / max(len(given), 1))
    else:
        rest = max(1.0 - sum(given), 0.0) / n_free
        disc = np.asarray([rest if w is None else w for w in group_weights], np.float64)
    disc = disc * (1.0 - goal.sum()) if len(group_weights) else disc
    out = np.concatenate([disc, goal])
    if out.sum() <= 0:
        raise ValueError(f"objective weights sum to zero: groups {group_weights}, goals {goal_weights}")
    return out / out.sum()


def root_xy(frame: LinkFrames) -> jax.Array:
    return frame.pos[0, :2]


def rotate_z(v: jax.Array, angle: jax.Array) -> jax.Array:
    """``v`` [2] or [3] turned by ``angle`` (rad) about the world z axis."""
    c, s = jnp.cos(angle), jnp.sin(angle)
    xy = jnp.stack([c * v[0] - s * v[1], s * v[0] + c * v[1]])
    return jnp.concatenate([xy, v[2:]])


def heading_angle(frame: LinkFrames) -> jax.Array:
    """Yaw of the root (pelvis) in the world (rad)."""
    return R.heading_angle(frame.quat[0])


def to_heading(frame: LinkFrames, v: jax.Array) -> jax.Array:
    """World vector(s) [..., 3] in the root's heading (yaw-only) frame."""
    inv = R.heading_inv(frame.quat[0])
    return R.quat_rotate(jnp.broadcast_to(inv, v.shape[:-1] + (4,)), v)
