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
``tasks.TASKS``.
"""

from __future__ import annotations

import dataclasses
from typing import Any, ClassVar

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from jaxmotion.motion.observations import LinkFrames
from jaxmotion.motion import rotations as R


@dataclasses.dataclass(frozen=True)
class LocationConfig:
    """Target location (defaults: the authors' walk/crouch settings, notes §1)."""

    radius: float = 0.5
    """A goal counts as reached inside this distance (m); the reward is then 1."""
    speed_range: tuple[float, float] = (1.2, 1.5)
    """Clip of the required speed (m/s) the reward asks for."""
    timer_range: tuple[int, int] = (90, 150)
    """Control steps a goal lasts: U{lo .. hi-1}."""
    v0_mean: float = 1.0
    v0_std: float = 0.25
    v0_range: tuple[float, float] = (0.0, 1.25)
    """The goal's distance is v0 * timer / 30 with v0 from this truncated normal (m/s)."""
    sharp_turns: bool = True
    """True: a goal in any direction; False: within ±60 degrees of the current heading."""
    max_overshoot: float = 3.0
    """End the episode when the distance to the goal has grown by this much (m) since it was set
    (0 disables)."""
    weight: float = 0.5
    """ω of the location objective."""


@dataclasses.dataclass(frozen=True)
class HeadingConfig:
    """Target heading and speed (the paper gives no formula; ours is in ``tasks/location.py``)."""

    speed_range: tuple[float, float] = (1.0, 1.5)
    """Target speed, uniform in this range (m/s)."""
    turn_deg: float = 90.0
    """Each new heading is the current facing ± U(0, turn_deg)."""
    timer_range: tuple[int, int] = (90, 150)
    """Control steps a heading lasts: U{lo .. hi-1}."""
    settle_steps: int = 30
    """Metrics skip this many steps after each new heading (time to turn)."""
    weight: float = 0.5


@dataclasses.dataclass(frozen=True)
class AimConfig:
    """Aiming: the right forearm points along a target direction (notes §1)."""

    yaw_deg: tuple[float, float] = (0.0, 45.0)
    """Aim direction: the horizontal root-to-target direction turned left by U(yaw range)..."""
    pitch_deg: tuple[float, float] = (0.0, 30.0)
    """... and up by U(pitch range)."""
    weight: float = 0.25
    """ω of the aim objective."""


@dataclasses.dataclass(frozen=True)
class JuggleConfig:
    """Juggling three balls (``tasks/juggle.py``; the schedule and reward are the authors')."""

    weight: float = 0.6
    """ω of the juggling reward (the authors': 0.6 juggling, 0.1 location, 0.06 arms, 0.24 body)."""


@dataclasses.dataclass(frozen=True)
class TennisConfig:
    """Tennis swing (``tasks/tennis.py``; the paper's formula is in an appendix we do not have,
    so this one is ours): a ball is fed beside the character every ``feed_every`` steps; hitting
    it pays for its outgoing speed and for where it would land."""

    feed_every: int = 60
    """Control steps between balls (60: 2 s)."""
    feed_forward: tuple[float, float] = (0.55, 0.85)
    feed_right: tuple[float, float] = (0.35, 0.65)
    feed_height: tuple[float, float] = (0.9, 1.3)
    """Where a ball appears, from the root's ground point in its heading frame (m): ahead, to the
    right (the racket side), above the floor; uniform in each range."""
    feed_up_speed: tuple[float, float] = (0.5, 1.5)
    """Its vertical speed upwards (m/s), as if tossed; no horizontal speed."""
    target_ahead: tuple[float, float] = (8.0, 12.0)
    target_side: tuple[float, float] = (-2.0, 2.0)
    """The landing target, drawn with each ball: ahead and to the left (m) in the heading frame."""
    target_speed: float = 10.0
    """Outgoing speed that earns the full speed half of the hit reward (m/s)."""
    landing_sigma: float = 2.0
    """Landing half of the hit reward: exp(-d^2 / (2 sigma^2)), d the landing error (m)."""
    touch_force: float = 1.0
    """A racket contact of at least this normal force (N) is a hit."""
    weight: float = 0.35
    """ω of the hit reward."""
    reach_weight: float = 0.15
    """ω of the reach reward exp(-4 d^2), d the racket head's distance to the ball before it is
    hit (our shaping; 0 leaves the paper's outcome-only reward)."""


@dataclasses.dataclass(frozen=True)
class TrackConfig:
    """Motion tracking (Perpetual Humanoid Control; notes phc.md §0-§3): follow the init clips
    frame by frame. Defaults: the authors' code."""

    goal: str = "rotation"
    """'rotation' (24 features per body) or 'keypoint' (positions and velocities only, 9)."""
    termination: str = "max"
    """'max': any body but the feet farther than ``termination_distance`` from its reference
    (the code, 0.25 m); 'mean': the mean over those bodies (the paper, 0.5 m)."""
    termination_distance: float = 0.25
    exponents: tuple[float, float, float, float] = (100.0, 10.0, 0.1, 0.1)
    """k of exp(-k * mean squared error) for position, rotation angle, linear and angular velocity."""
    term_weights: tuple[float, float, float, float] = (0.5, 0.3, 0.1, 0.1)
    """Weights of those four terms (they sum to 1: a perfect frame pays 1)."""
    weight: float = 0.5
    """ω of the imitation objective (the paper's 0.5 task / 0.5 motion prior)."""
    residual: bool = False
    """False: the PD target is the joint range's mid-point + the action (the authors' code).
    True: it is the reference's joint angles one control step ahead (clamped to the joint ranges)
    + the action, so an untrained policy already servos towards the clip and learning only has
    to add the corrections that keep it balanced."""
    energy_coef: float = 0.0005
    """The energy penalty -c * sum_j |tau_j qdot_j| (linear mechanical power, the authors' code;
    the paper prints the square) added to the imitation reward (the scene reports no power on an
    episode's first 3 steps); 0 disables it."""


@dataclasses.dataclass(frozen=True)
class BoxingConfig:
    """Boxing rules and rewards (Won et al. 2021, Eqs. 1-5; the authors' variants as switches,
    notes won2021.md §0 and §3). Defaults: the paper."""

    damage_clip: float = 200.0
    """Each side's scoring contact force is clipped here (N) before the difference is taken."""
    touch_threshold: float = 1.0
    """Scoring forces below this (N) count as no touch."""
    close_k: float = 3.0
    close_squared: bool = True
    """r_close = exp(-k d^2) (the paper) or exp(-k d) (the code); d: the nearest glove-target distance."""
    facing_k: float = 5.0
    energy_deadzone: float = 100.0
    """r_energy = -gate(l) * max(0, |dq_t - dq_{t-1}|^2 - deadzone), joint velocities per control
    step (the code's form of the paper's angular accelerations); gate(l) = 1 - exp(-50 max(0, l - 1)^2)."""
    stuck_distance: float = 0.4
    stuck_seconds: float = 5.0
    rope_margin: float = 0.15
    """'Near the ropes': the root within this of the ring's inner edge (m)."""
    rope_seconds: float = 5.0
    start_distance: tuple[float, float] = (0.7, 3.0)
    weights: tuple[float, float, float, float, float] = (1.0, 0.2, 0.05, 0.001, 30.0)
    """ω of (match, close, facing, energy, penalty): the paper's Table 1."""


@dataclasses.dataclass(frozen=True)
class FencingConfig:
    """Fencing rules and rewards (Won et al. 2021, Eq. 7; notes won2021.md §3). Defaults: the paper."""

    touch_threshold: float = 1.0
    """A touch: blade contact on a target with at least this normal force (N)."""
    counter_seconds: float = 1.0
    """A counter-touch within this long after the first touch makes the bout a draw."""
    piste: tuple[float, float] = (12.0, 2.0)
    """Length and width of the piste (m): leaving it is a penalty that ends the bout."""
    win_reward: float = 1.0
    """r_match paid once at the result: +win to the winner, -win to the loser, 0 for a draw (the code: 10)."""
    close_k: float = 3.0
    start_distance: float = 4.0
    weights: tuple[float, float, float] = (1.0, 0.2, 30.0)
    """ω of (match, close, penalty)."""


@dataclasses.dataclass(frozen=True)
class TaskConfig:
    """Which task the scene runs (a name in ``tasks.TASKS``) and the settings of each."""

    name: str = "imitate"
    location: LocationConfig = LocationConfig()
    heading: HeadingConfig = HeadingConfig()
    aim: AimConfig = AimConfig()
    track: TrackConfig = TrackConfig()
    juggle: JuggleConfig = JuggleConfig()
    boxing: BoxingConfig = BoxingConfig()
    fencing: FencingConfig = FencingConfig()
    tennis: TennisConfig = TennisConfig()


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
    evaluator: ClassVar[str] = "imitation"
    mines_clips: ClassVar[bool] = False
    """Resets pick the clips it tracks, so hard-negative mining can reweight them."""
    """How `python -m jaxmotion.eval` evaluates a run of this task (a key of `evaluation.EVALUATORS`)."""
    min_reward: ClassVar[float] = 0.0
    """The lowest reward any of this task's objectives pays per step."""

    def __init__(self, cfg: TaskConfig, env):
        self.cfg = cfg
        self.env = env

    goal_parts: ClassVar[tuple[tuple[str, int], ...]] = ()
    """The goal features as named blocks (name, size), in observation order. A frozen meta
    policy (``meta.py``) finds its own goal blocks in a new task's goal by these names."""

    @property
    def goal_size(self) -> int:
        return sum(n for _, n in self.goal_parts)

    def weights(self) -> tuple[float, ...]:
        """ω of each reward, as configured."""
        return ()

    def init(self, rng: jax.Array, frame: LinkFrames, start: tuple[jax.Array, jax.Array] | None = None) -> Any:
        """``start``: (clip index, time in s) of the reference state the character was reset to."""
        return jnp.zeros((0,), jnp.float32)

    def observe(self, goal: Any, frame: LinkFrames) -> jax.Array:
        return jnp.zeros((0,), jnp.float32)

    def step(self, goal: Any, prev: LinkFrames, frame: LinkFrames, rng: jax.Array,
             power: jax.Array | None = None) -> TaskStep:
        return TaskStep(goal=goal, rewards=jnp.zeros((0,), jnp.float32),
                        terminated=jnp.zeros((), bool), info={})

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
        raise ValueError(f"goal weights {tuple(goal_weights)} must be non-negative and sum below 1 "
                         f"when there are discriminators")
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
