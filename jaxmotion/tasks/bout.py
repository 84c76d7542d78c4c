"""Two-player tasks: the rules, rewards and observations of boxing and fencing (Won et al. 2021).

A bout task is a task of the two-player scene (``envs/bout.py``); every function sees both
players' link frames ``frame`` ([2, nb, ...]) and reports per player (leading axis 2):

* ``start(rng) -> (xy [2, 2], yaw [2])``: where the players begin, facing each other;
* ``init(rng, frame) -> goal``: the rules' state (timers, touches);
* ``observe(goal, frame, k) -> [goal_size]``: player ``k``'s task features (paper Eq. 6);
* ``step(goal, prev, frame, forces, fell, qvel0, qvel, steps, rng) -> TaskStep``: ``forces`` [2]
  is each player's scoring contact force on the opponent (N, the maximum over the control
  step's substeps),
  ``fell`` [2] its fall, ``qvel0``/``qvel`` [2, nv] its joint velocities before/after the step;
  rewards [2, R], ``terminated`` [2] (that player's bout is over: its penalty or a result).

The task observation, in the player's heading frame (``interaction_obs``): its position and
facing in its own view of the arena (player 1's turned by 180 degrees, so the two players of a
scene that is symmetric under that turn see the same features), the opponent's links (position
and velocity), for each of its own scorer points (glove centres; three blade points) the
opponent's targets and scorer points relative to it, and for each of its own targets the
opponent's scorer points. Sizes: boxing 4 + 6 nb + 6 S (T + S) + 6 T S = 190 for 15 bodies,
2 gloves and 3 targets (head, chest, belly); the authors' per-link contact flags are not included.
"""

from __future__ import annotations

import dataclasses
from typing import Annotated, ClassVar

import jax
import jax.numpy as jnp
from flax import struct

from jaxmotion.config.checks import Min, NonNegative, Ordered, Positive
from jaxmotion.motion.observations import LinkFrames, heading_frame
from jaxmotion.motion import rotations as R
from jaxmotion.physics.arena import SPORTS
from jaxmotion.tasks.base import Task, TaskStep


@dataclasses.dataclass(frozen=True)
class BoxingConfig:
    """Boxing rules and rewards (Won et al. 2021, Eqs. 1-5; the authors' variants as switches,
    notes won2021.md §0 and §3). Defaults: the paper."""

    damage_clip: Positive = 200.0
    """Each side's scoring contact force is clipped here (N) before the difference is taken."""
    touch_threshold: NonNegative = 1.0
    """Scoring forces below this (N) count as no touch."""
    touch_interval: NonNegative = 0.5
    """A hit is counted at its onset: after a player's counted hit, its scoring contacts are
    ignored for this long (s; the authors' ``touch_interval``), so a glove held on a target
    pays once per interval, not on every step of the contact. 0: every step of contact pays
    (the paper's Eq. 2 read literally)."""
    close_k: NonNegative = 3.0
    close_squared: bool = True
    """r_close = exp(-k d^2) (the paper) or exp(-k d) (the code); d: the nearest glove-target distance."""
    facing_k: NonNegative = 5.0
    energy_deadzone: NonNegative = 100.0
    """r_energy = -gate(l) * max(0, |dq_t - dq_{t-1}|^2 - deadzone), joint velocities per control
    step (the code's form of the paper's angular accelerations); gate(l) = 1 - exp(-50 max(0, l - 1)^2)."""
    stuck_distance: NonNegative = 0.4
    stuck_seconds: Positive = 5.0
    rope_margin: NonNegative = 0.15
    """'Near the ropes': the root within this of the ring's inner edge (m)."""
    rope_seconds: Positive = 5.0
    start_distance: Annotated[tuple[float, float], Min(0), Ordered()] = (0.7, 3.0)
    weights: Annotated[tuple[float, float, float, float, float], Min(0)] = (1.0, 0.2, 0.05, 0.001, 30.0)
    """ω of (match, close, facing, energy, penalty): the paper's Table 1."""


@dataclasses.dataclass(frozen=True)
class FencingConfig:
    """Fencing rules and rewards (Won et al. 2021, Eq. 7; notes won2021.md §3). Defaults: the paper."""

    touch_threshold: NonNegative = 1.0
    """A touch: blade contact on a target with at least this normal force (N)."""
    counter_seconds: NonNegative = 1.0
    """A counter-touch within this long after the first touch makes the bout a draw."""
    piste: Annotated[tuple[float, float], Min(0, open=True)] = (12.0, 2.0)
    """Length and width of the piste (m): leaving it is a penalty that ends the bout."""
    win_reward: NonNegative = 1.0
    """r_match paid once at the result: +win to the winner, -win to the loser, 0 for a draw (the code: 10)."""
    close_k: NonNegative = 3.0
    close_squared: bool = False
    """r_close = exp(-k d) (the authors' code, the default) or exp(-k d^2) (the paper's boxing
    Eq. 3); d: the nearest distance from a blade point to an opponent target. At the 4-m start
    d is about 3.3 m (zero pose; 2.8-4.3 m, median 3.25 m over resets from the fencing clips),
    where exp(-3 d^2) is about 1e-14 (at most 1e-10): below the critic's error and the
    advantage standardisation's eps (1e-8), so no closeness signal reaches a policy that has
    not yet walked up. exp(-3 d) there is about 5e-5 (2e-6 to 2.5e-4) and grows 20-fold a metre."""
    start_distance: Positive = 4.0
    """Root-to-root distance at the start (m). The authors start from a capture of two fencers
    at fencing distance but give no number (notes won2021.md §5); 4 m is the distance between a
    real piste's on-guard lines."""
    weights: Annotated[tuple[float, float, float], Min(0)] = (1.0, 0.2, 30.0)
    """ω of (match, close, penalty)."""


def _points(f: LinkFrames, bodies: jax.Array, offsets: jax.Array) -> tuple[jax.Array, jax.Array]:
    """World positions and velocities [n, 3] of body-fixed points of one player."""
    q = f.quat[bodies]
    r = R.quat_rotate(q, offsets)
    return f.pos[bodies] + r, f.lin_vel[bodies] + jnp.cross(f.ang_vel[bodies], r)


@struct.dataclass
class BoxingState:
    stuck_steps: jax.Array  # steps the players have been within stuck_distance
    rope_steps: jax.Array  # [2] steps each player has been near the ropes
    hit_wait: jax.Array  # [2] steps before each player's scoring contacts count again (0: now)


@struct.dataclass
class FencingState:
    touched: jax.Array  # [2] bool: each player has touched the opponent
    first: jax.Array  # step of the first touch; -1 before it
    since: jax.Array  # seconds since the first touch (0 before it)


class BoutTask(Task):
    """What boxing and fencing share: placement, the interaction features, closeness, falls."""

    evaluator = "bouts"

    two_player: ClassVar[bool] = True
    sport: ClassVar[str] = ""

    def __init__(self, cfg, env):
        super().__init__(cfg, env)
        if env.cfg.arena.sport != self.sport:
            raise ValueError(f"task {cfg.name!r} needs env.arena.sport={self.sport!r}, got {env.cfg.arena.sport!r}")
        ch = env.character
        sp = SPORTS[self.sport]
        self._sb = jnp.asarray([ch.body_index(b) for b, _ in sp.scorer_points], jnp.int32)
        self._so = jnp.asarray([o for _, o in sp.scorer_points], jnp.float32)
        self._tb = jnp.asarray([ch.body_index(b) for b, _ in sp.target_points], jnp.int32)
        self._to = jnp.asarray([o for _, o in sp.target_points], jnp.float32)
        S, T, nb = len(sp.scorer_points), len(sp.target_points), ch.num_bodies
        self.goal_parts = (
            ("arena", 4),
            ("opponent", 6 * nb),
            ("scorers", 6 * S * (T + S)),
            ("targets", 6 * T * S),
        ) + self.extra_parts

    extra_parts: ClassVar[tuple[tuple[str, int], ...]] = ()

    def weights(self) -> tuple[float, ...]:
        return tuple(self.sub.weights)

    @property
    def sub(self):
        return getattr(self.cfg, self.sport)

    def interaction_obs(self, frame: LinkFrames, k: int) -> jax.Array:
        me = jax.tree.map(lambda x: x[k], frame)
        op = jax.tree.map(lambda x: x[1 - k], frame)
        origin, inv = heading_frame(me.pos[0], me.quat[0])
        rot = lambda v: R.quat_rotate(jnp.broadcast_to(inv, v.shape[:-1] + (4,)), v)
        yaw = R.heading_angle(me.quat[0]) + k * jnp.pi
        xy = me.pos[0, :2] * (1.0 - 2.0 * k)
        arena = jnp.concatenate([xy, jnp.stack([jnp.cos(yaw), jnp.sin(yaw)])])
        opp = jnp.concatenate([rot(op.pos - origin), rot(op.lin_vel)], -1).reshape(-1)
        sp_me, sv_me = _points(me, self._sb, self._so)
        tp_me, tv_me = _points(me, self._tb, self._to)
        sp_op, sv_op = _points(op, self._sb, self._so)
        tp_op, tv_op = _points(op, self._tb, self._to)
        # Own scorer -> opponent targets and scorers; own target -> opponent scorers.
        qp, qv = jnp.concatenate([tp_op, sp_op]), jnp.concatenate([tv_op, sv_op])
        scor = jnp.concatenate([rot(qp[None] - sp_me[:, None]), rot(qv[None] - sv_me[:, None])], -1)
        targ = jnp.concatenate([rot(sp_op[None] - tp_me[:, None]), rot(sv_op[None] - tv_me[:, None])], -1)
        return jnp.concatenate([arena, opp, scor.reshape(-1), targ.reshape(-1)])

    def closeness(self, frame: LinkFrames) -> jax.Array:
        """[2] the nearest distance from each player's scorer points to the opponent's targets."""
        out = []
        for k in range(2):
            sp, _ = _points(jax.tree.map(lambda x, k=k: x[k], frame), self._sb, self._so)
            tp, _ = _points(jax.tree.map(lambda x, k=k: x[1 - k], frame), self._tb, self._to)
            out.append(jnp.min(jnp.linalg.norm(sp[:, None] - tp[None], axis=-1)))
        return jnp.stack(out)

    def close_reward(self, frame: LinkFrames) -> jax.Array:
        """[2] r_close = exp(-k d^2) or exp(-k d) (``close_squared``) of ``closeness``."""
        c = self.sub
        d = self.closeness(frame)
        return jnp.exp(-c.close_k * (d**2 if c.close_squared else d))

    def markers(self, goal, frame: LinkFrames) -> dict[str, jax.Array]:
        return {}


class Boxing(BoutTask):
    """Boxing (paper Eqs. 1-5): damage difference, closeness, facing, energy, penalties.

    Damage is paid per hit, at its onset (the authors' ``touch_interval``): paying the clipped
    force on every step of a contact would reward holding a glove on the opponent's chest as a
    flurry of punches."""

    settings = (("boxing", BoxingConfig),)

    sport = "boxing"
    reward_names = ("match", "close", "facing", "energy", "penalty")
    min_reward = -float("inf")  # the energy term has no floor

    def start(self, rng: jax.Array) -> tuple[jax.Array, jax.Array]:
        """Roots 0.7-3 m apart (uniform), their midpoint within 1 m of the centre, facing each other."""
        k_m, k_d, k_a = jax.random.split(rng, 3)
        lo, hi = self.sub.start_distance
        mid = jax.random.uniform(k_m, (2,), minval=-1.0, maxval=1.0)
        d = jax.random.uniform(k_d, (), minval=lo, maxval=hi)
        a = jax.random.uniform(k_a, (), minval=-jnp.pi, maxval=jnp.pi)
        u = jnp.stack([jnp.cos(a), jnp.sin(a)])
        return jnp.stack([mid - 0.5 * d * u, mid + 0.5 * d * u]), jnp.stack([a, a + jnp.pi])

    def init(self, rng, frame, start=None) -> BoxingState:
        zeros = jnp.zeros((2,), jnp.int32)
        return BoxingState(stuck_steps=jnp.zeros((), jnp.int32), rope_steps=zeros, hit_wait=zeros)

    def observe(self, goal, frame, k) -> jax.Array:
        return self.interaction_obs(frame, k)

    def hits(self, goal: BoxingState, forces: jax.Array) -> tuple[jax.Array, jax.Array]:
        """(onset [2] bool, next ``hit_wait`` [2]): a player's scoring contact counts when its
        wait is over; a counted hit makes it wait ``touch_interval`` (whole control steps: 15 at
        30 Hz, so a held contact counts on steps 1, 16, 31, ...). Each player's wait is its own."""
        window = int(round(self.sub.touch_interval / self.env.dt))
        onset = (forces >= self.sub.touch_threshold) & (goal.hit_wait <= 0)
        wait = jnp.where(onset, max(window - 1, 0), jnp.maximum(goal.hit_wait - 1, 0))
        return onset, wait.astype(jnp.int32)

    def step(self, goal: BoxingState, prev, frame, forces, fell, qvel0, qvel, steps, rng) -> TaskStep:
        c, dt = self.sub, self.env.dt
        onset, hit_wait = self.hits(goal, forces)
        dealt = jnp.where(onset, jnp.minimum(forces, c.damage_clip), 0.0)
        match = dealt - dealt[::-1]
        close = self.close_reward(frame)
        root = frame.pos[:, 0, :2]
        to_op = root[::-1] - root
        dist = jnp.linalg.norm(to_op, axis=-1)
        v_hat = to_op / jnp.maximum(dist, 1e-6)[:, None]
        yaw = R.heading_angle(frame.quat[:, 0])
        face = jnp.stack([jnp.cos(yaw), jnp.sin(yaw)], -1)
        facing = jnp.exp(-c.facing_k * (jnp.sum(face * v_hat, -1) - 1.0) ** 2)
        gate = 1.0 - jnp.exp(-50.0 * jnp.maximum(dist - 1.0, 0.0) ** 2)
        dq = jnp.sum((qvel[:, 6:] - qvel0[:, 6:]) ** 2, -1)
        energy = -gate * jnp.maximum(dq - c.energy_deadzone, 0.0)
        stuck_steps = jnp.where(dist[0] < c.stuck_distance, goal.stuck_steps + 1, 0)
        half = self.env.cfg.arena.ring_size / 2 - c.rope_margin
        near = jnp.any(jnp.abs(root) > half, -1) & (self.env.cfg.arena.ring_size > 0)
        rope_steps = jnp.where(near, goal.rope_steps + 1, 0)
        stuck = stuck_steps > int(round(c.stuck_seconds / dt))  # whole steps: "> 5 s" is the 151st at 30 Hz
        roped = rope_steps > int(round(c.rope_seconds / dt))
        penalised = fell | stuck | roped
        rewards = jnp.stack([match, close, facing, energy, -penalised.astype(jnp.float32)], -1)
        info = {
            "damage_dealt": dealt,
            "damage_received": dealt[::-1],
            "hit": onset,
            "contact": forces >= c.touch_threshold,
            "close": close,
            "distance": dist,
            "fall": fell,
            "stuck": jnp.broadcast_to(stuck, (2,)),
            "ropes": roped,
        }
        return TaskStep(
            goal=BoxingState(stuck_steps=stuck_steps, rope_steps=rope_steps, hit_wait=hit_wait),
            rewards=rewards,
            terminated=penalised,
            info=info,
        )


class Fencing(BoutTask):
    """Fencing (paper Eq. 7): the first touch wins unless countered within 1 s (a draw);
    simultaneous touches draw; the result is paid once, at the end; falls and leaving the piste
    are penalties that end the bout."""

    settings = (("fencing", FencingConfig),)

    sport = "fencing"
    reward_names = ("match", "close", "penalty")
    min_reward = -1.0
    extra_parts = (("trigger", 3),)

    def start(self, rng: jax.Array) -> tuple[jax.Array, jax.Array]:
        """On the piste's axis, ``start_distance`` apart, facing each other; sides at random."""
        side = jnp.where(jax.random.bernoulli(rng), 1.0, -1.0)
        h = 0.5 * self.sub.start_distance
        xy = jnp.asarray([[-h, 0.0], [h, 0.0]]) * side
        yaw = jnp.where(side > 0, jnp.asarray([0.0, jnp.pi]), jnp.asarray([jnp.pi, 0.0]))
        return xy, yaw

    def init(self, rng, frame, start=None) -> FencingState:
        return FencingState(
            touched=jnp.zeros((2,), bool), first=-jnp.ones((), jnp.int32), since=jnp.zeros((), jnp.float32)
        )

    def observe(self, goal: FencingState, frame, k) -> jax.Array:
        trig = jnp.stack([goal.touched[k], goal.touched[1 - k]]).astype(jnp.float32)
        return jnp.concatenate([self.interaction_obs(frame, k), trig, goal.since[None]])

    def rules(self, goal: FencingState, touch: jax.Array, steps: jax.Array):
        """The touch rules on one step: (next state, ended, win [2] float: +1 winner, -1 loser, 0 draw).

        A counter-touch up to ``counter_seconds`` after the first touch (inclusive) is a draw, as
        are simultaneous touches; once that window has passed, the first toucher has won (the
        result falls on the first step after the window, whatever is touched then)."""
        window = int(round(self.sub.counter_seconds / self.env.dt))
        over = (goal.first >= 0) & (steps - goal.first > window)
        touched = goal.touched | (touch & ~over)
        first = jnp.where((goal.first < 0) & jnp.any(touch), steps, goal.first)
        both = touched[0] & touched[1]
        ended = both | over
        single = (touched & ~touched[::-1]).astype(jnp.float32)
        win = jnp.where(ended & ~both, single - single[::-1], 0.0)
        since = jnp.where(first >= 0, (steps - first) * self.env.dt, 0.0).astype(jnp.float32)
        return FencingState(touched=touched, first=first, since=since), ended, win

    def step(self, goal: FencingState, prev, frame, forces, fell, qvel0, qvel, steps, rng) -> TaskStep:
        c = self.sub
        touch = forces >= c.touch_threshold
        new, ended, win = self.rules(goal, touch, steps)
        close = self.close_reward(frame)
        root = frame.pos[:, 0, :2]
        out = (jnp.abs(root[:, 0]) > c.piste[0] / 2) | (jnp.abs(root[:, 1]) > c.piste[1] / 2)
        penalised = fell | out
        rewards = jnp.stack([win * c.win_reward, close, -penalised.astype(jnp.float32)], -1)
        info = {
            "touch": touch,
            "win": win > 0,
            "loss": win < 0,
            "draw": jnp.broadcast_to(ended, (2,)) & (win == 0),
            "result": jnp.broadcast_to(ended, (2,)),
            "close": close,
            "distance": jnp.broadcast_to(jnp.linalg.norm(root[0] - root[1]), (2,)),
            "fall": fell,
            "out": out,
        }
        return TaskStep(goal=new, rewards=rewards, terminated=penalised | ended, info=info)
