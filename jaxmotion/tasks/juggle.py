"""Juggling three balls while walking to a target location (the authors'
``ICCGANHumanoidJugglingTarget``; paper §6.4 Fig. 5d; notes §1).

**Balls.** Three balls of radius 0.05 m that the hands throw and catch in a cascade. The authors'
collision filters keep the balls from touching each other or the hands and forearms, and a catch
is a teleport-attach, so a ball interacts with the character only through the hand that holds
it. With three props in the scene (``PhysicsConfig.props``, ``physics/props.py``; what
``goal/juggle+walk`` runs) the balls are free bodies of the MuJoCo/MJX scene: the physics flies
them and stops them on the floor, and the task reads them after every step (``sense``) and
writes the ones it holds, throws or catches before the next (``place``). Props touch neither the
body nor each other (the authors' could bounce off the torso, head or legs). Without props the
balls are the task's own state, integrated exactly (ballistic under gravity, resting where they
reach the floor), which is what a scene-free test drives.

**Schedule** (control steps at 30 Hz): each hand throws every 20 steps, the left at 0, 20, ...,
the right at 10, 30, ... The left hand starts with balls 0 and 2, the right with ball 1. A ball
thrown at step t by one hand is the other hand's to catch and is thrown again by it at t + 30,
so its flight plus dwell is 30 steps; the target release speed is v* = g (3 * 10 - 12) / 2 / 30
= 2.94 m/s upward (18 steps of flight, 12 of dwell). A released ball keeps the hand's velocity.
A free, descending ball within 0.1 m of the hand that should catch it is caught and then follows
that hand. One step before its next throw a ball that is still free is put into the hand anyway
and flagged *missed*, so balls are never lost.

**Reward per hand** (the task reward is the mean of the two hands): on the step a hand releases a
ball, exp(-5 (v_z / v* - 1)^2). On other steps, once all three balls have been released:
0.1 exp(-20 dh^2) + 0.9 [not missed] (0.9 exp(-20 d^2) + 0.2 exp(-d^2)), where d is the distance
from the hand to where its ball will be when it falls to the hand's height (at most the time left
before that ball must be thrown again) and dh the ball's release height minus the hand's height
(0 once caught). A hand holding the ball it should catch scores d = dh = 0.

**Goal** (19 juggling features after the location's 4): per hand its target ball (position
relative to the root's ground point and velocity, heading frame; zero when caught), the ball
the character throws next, and the left hand's throw phase in [0, 1). The authors' 23 dims, read
from their description.

**Metrics** (``eval``): catches per throw (catches over catches + misses), the longest streak
of catches without a miss in an episode, and the mean |v_z - v*| of the releases; plus the
location task's.
"""

from __future__ import annotations

import dataclasses
import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from jaxmotion.config.checks import NonNegative
from jaxmotion.motion.observations import LinkFrames
from jaxmotion.tasks.base import TaskStep, root_xy, to_heading
from jaxmotion.tasks.location import Location, LocationConfig, LocationGoal


@dataclasses.dataclass(frozen=True)
class JuggleConfig:
    """Juggling three balls (``tasks/juggle.py``; the schedule and reward are the authors')."""

    weight: NonNegative = 0.6
    """ω of the juggling reward (the authors': 0.6 juggling, 0.1 location, 0.06 arms, 0.24 body)."""


G = 9.81
RADIUS = 0.05
PERIOD = 20  # steps between two throws of one hand
OFFSETS = (0, 10)  # first throw of the left, right hand
FLIGHT_DWELL = 30  # a ball is thrown again 30 steps after its last throw
DWELL = 12
CATCH_DISTANCE = 0.1
LEFT, RIGHT = 0, 1


def target_speed(dt_steps: float = 1 / 30) -> float:
    """v* = g (flight + dwell - dwell) / 2, with the flight in seconds at the control rate."""
    return 0.5 * G * (FLIGHT_DWELL - DWELL) * dt_steps


@struct.dataclass
class Balls:
    pos: jax.Array  # [3, 3] world
    vel: jax.Array  # [3, 3]
    holder: jax.Array  # [3] int: -1 free, 0 left, 1 right
    to_hand: jax.Array  # [3] int: the hand that catches (or holds) it
    throw_at: jax.Array  # [3] int: the step at which to_hand throws it next
    missed: jax.Array  # [3] bool: forced into the hand since its last throw
    release_h: jax.Array  # [3] release height of its last throw
    released: jax.Array  # [3] bool: thrown at least once


@struct.dataclass
class JuggleGoal:
    loc: LocationGoal
    balls: Balls
    t: jax.Array  # int: steps since the juggling started


def initial_balls(hands: jax.Array) -> Balls:
    """Balls 0 and 2 in the left hand, ball 1 in the right; ``hands`` [2, 3]."""
    holder = jnp.asarray([LEFT, RIGHT, LEFT], jnp.int32)
    return Balls(
        pos=hands[holder],
        vel=jnp.zeros((3, 3)),
        holder=holder,
        to_hand=holder,
        throw_at=jnp.asarray([0, 10, 20], jnp.int32),
        missed=jnp.zeros(3, bool),
        release_h=hands[holder, 2],
        released=jnp.zeros(3, bool),
    )


def fly(pos: jax.Array, vel: jax.Array, dt: float) -> tuple[jax.Array, jax.Array]:
    """Exact ballistic step; a ball reaching the floor stays there at rest."""
    g = jnp.asarray([0.0, 0.0, -G])
    p = pos + vel * dt + 0.5 * g * dt * dt
    v = vel + g * dt
    down = p[..., 2:3] <= RADIUS
    return jnp.where(down, p.at[..., 2].set(RADIUS), p), jnp.where(down, 0.0, v)


def landing_point(pos: jax.Array, vel: jax.Array, height: jax.Array, t_max: jax.Array) -> jax.Array:
    """Where a free ball is when it falls to ``height``, but at most ``t_max`` s ahead (and not
    before now: a ball already below that height and falling is where it is)."""
    # z(t) = z + vz t - g t^2 / 2 = height: the later root.
    a, b, c = -0.5 * G, vel[..., 2], pos[..., 2] - height
    disc = jnp.maximum(b * b - 4 * a * c, 0.0)
    t = (-b - jnp.sqrt(disc)) / (2 * a)
    t = jnp.clip(t, 0.0, jnp.maximum(t_max, 0.0))
    return pos + vel * t[..., None] + 0.5 * jnp.asarray([0.0, 0.0, -G]) * (t * t)[..., None]


def step_balls(b: Balls, t: jax.Array, hands: jax.Array, hand_vel: jax.Array, dt: float, flight: bool = True):
    """One control step of the schedule at step ``t``: throws, flight, catches, forced catches.
    ``flight`` False: the free balls have flown already (the physics did; ``b`` holds where they
    are now) and thrown balls are left at the hand with its velocity for the physics to fly.

    Returns (balls, thrown [3] bool, caught [3] bool, forced [3] bool)."""
    held = b.holder >= 0
    thrown = held & (t == b.throw_at)
    # Released balls keep the hand's velocity and now belong to the other hand.
    vel = jnp.where(thrown[:, None], hand_vel[b.holder], b.vel)
    pos = jnp.where(held[:, None], hands[jnp.maximum(b.holder, 0)], b.pos)
    b = b.replace(
        pos=pos,
        vel=vel,
        holder=jnp.where(thrown, -1, b.holder),
        to_hand=jnp.where(thrown, 1 - b.to_hand, b.to_hand),
        throw_at=jnp.where(thrown, b.throw_at + FLIGHT_DWELL, b.throw_at),
        missed=jnp.where(thrown, False, b.missed),
        release_h=jnp.where(thrown, pos[:, 2], b.release_h),
        released=b.released | thrown,
    )
    free = b.holder < 0
    if flight:
        fp, fv = fly(b.pos, b.vel, dt)
        pos, vel = jnp.where(free[:, None], fp, b.pos), jnp.where(free[:, None], fv, b.vel)
    else:
        pos, vel = b.pos, b.vel
    dist = jnp.linalg.norm(pos - hands[b.to_hand], axis=-1)
    caught = free & ~thrown & (vel[:, 2] < 0) & (dist < CATCH_DISTANCE)
    forced = free & ~caught & (t + 1 >= b.throw_at)
    take = caught | forced
    holder = jnp.where(take, b.to_hand, b.holder)
    pos = jnp.where(take[:, None], hands[b.to_hand], pos)
    vel = jnp.where(take[:, None], hand_vel[b.to_hand], vel)
    return b.replace(pos=pos, vel=vel, holder=holder, missed=b.missed | forced), thrown, caught, forced


def target_ball(b: Balls, hand: int) -> tuple[jax.Array, jax.Array]:
    """(index, exists) of the ball ``hand`` must catch next: a free ball of that hand, the
    earliest due; else the hand's held ball that it catches (so d = 0)."""
    mine = b.to_hand == hand
    key = jnp.where(mine & (b.holder < 0), b.throw_at, jnp.iinfo(jnp.int32).max)
    i = jnp.argmin(key)
    return i, key[i] < jnp.iinfo(jnp.int32).max


def hand_rewards(
    b: Balls, thrown: jax.Array, hands: jax.Array, hand_vel: jax.Array, t: jax.Array, dt: float, v_star: float
) -> jax.Array:
    """[2] per-hand juggling rewards after the step (see the module docstring)."""
    out = []
    for h in (LEFT, RIGHT):
        threw = thrown & (b.to_hand == 1 - h)  # a ball this hand released this step
        vz = hand_vel[h, 2]  # the release velocity is the hand's
        r_release = jnp.exp(-5.0 * (vz / v_star - 1.0) ** 2)
        i, pending = target_ball(b, h)
        t_left = (b.throw_at[i] - 1 - t).astype(jnp.float32) * dt
        land = landing_point(b.pos[i], b.vel[i], hands[h, 2], t_left)
        d = jnp.where(pending, jnp.linalg.norm(land - hands[h]), 0.0)
        dh = jnp.where(pending, b.release_h[i] - hands[h, 2], 0.0)
        ok = ~jnp.where(pending, b.missed[i], False)
        r_catch = 0.1 * jnp.exp(-20.0 * dh**2) + 0.9 * ok * (0.9 * jnp.exp(-20.0 * d**2) + 0.2 * jnp.exp(-(d**2)))
        r_catch = jnp.where(b.released.all(), r_catch, 0.0)
        out.append(jnp.where(threw.any(), r_release, r_catch))
    return jnp.stack(out)


class JuggleLocation(Location):
    """Juggle three balls while going to a target location."""

    settings = (("location", LocationConfig), ("juggle", JuggleConfig))

    reward_names = ("juggling", "location")
    goal_parts = (("location", 4), ("juggling", 19))
    min_reward = 0.0

    def __init__(self, cfg, env):
        super().__init__(cfg, env)
        ch = env.character
        self._hands = jnp.asarray([ch.body_index("left_hand"), ch.body_index("right_hand")])
        self._v_star = target_speed(env.dt)
        props = env.cfg.physics.props if hasattr(env, "cfg") else ()
        if len(props) not in (0, 3):
            raise ValueError(f"juggling needs three balls in the scene (env.physics.props) or none, got {len(props)}")
        self._physical = len(props) == 3

    def weights(self):
        return (self.cfg.juggle.weight, self.cfg.location.weight)

    def hands(self, frame: LinkFrames) -> tuple[jax.Array, jax.Array]:
        return frame.pos[self._hands], frame.lin_vel[self._hands]

    def init(self, rng, frame, start=None):
        return JuggleGoal(
            loc=self.new_goal(rng, frame), balls=initial_balls(self.hands(frame)[0]), t=jnp.zeros((), jnp.int32)
        )

    def observe(self, goal: JuggleGoal, frame) -> jax.Array:
        b = goal.balls
        ground = jnp.concatenate([root_xy(frame), jnp.zeros((1,))])
        feat = lambda i: jnp.concatenate([to_heading(frame, b.pos[i] - ground), to_heading(frame, b.vel[i])])
        parts = []
        for h in (LEFT, RIGHT):
            i, pending = target_ball(b, h)
            parts.append(jnp.where(pending, feat(i), 0.0))
        nxt = jnp.argmin(jnp.where(b.holder >= 0, b.throw_at, jnp.iinfo(jnp.int32).max))
        parts.append(feat(nxt))
        phase = jnp.mod(goal.t - OFFSETS[LEFT], PERIOD).astype(jnp.float32) / PERIOD
        return jnp.concatenate([super().observe(goal.loc, frame)] + parts + [phase[None]])

    def step(self, goal: JuggleGoal, prev, frame, rng, power=None) -> TaskStep:
        hands, hand_vel = self.hands(frame)
        balls, thrown, caught, forced = step_balls(
            goal.balls, goal.t, hands, hand_vel, self.env.dt, flight=not self._physical
        )
        r = hand_rewards(balls, thrown, hands, hand_vel, goal.t, self.env.dt, self._v_star).mean()
        loc = super().step(goal.loc, prev, frame, rng)
        # |v_z - v*| of this step's release (the hand that threw; 0 when none did).
        thrower = jnp.where(thrown.any(), 1 - jnp.max(jnp.where(thrown, balls.to_hand, 0)), 0)
        info = dict(
            loc.info,
            throws=thrown.sum(),
            catches=caught.sum(),
            misses=forced.sum(),
            release_error=jnp.where(thrown.any(), jnp.abs(hand_vel[thrower, 2] - self._v_star), 0.0),
        )
        return TaskStep(
            goal=JuggleGoal(loc=loc.goal, balls=balls, t=goal.t + 1),
            rewards=jnp.concatenate([r[None], loc.rewards]),
            terminated=loc.terminated,
            info=info,
        )

    def sense(self, goal: JuggleGoal, props) -> JuggleGoal:
        """Free balls where the physics flew them; held balls stay with their hand."""
        b = goal.balls
        free = (b.holder < 0)[:, None]
        return goal.replace(
            balls=b.replace(
                pos=jnp.where(free, props.qpos[:, :3], b.pos), vel=jnp.where(free, props.qvel[:, :3], b.vel)
            )
        )

    def place(self, goal: JuggleGoal, props):
        """Every ball where the task has it: held and just-thrown balls at the hand with its
        velocity; a free ball is written back unchanged (where ``sense`` read it)."""
        b = goal.balls
        return props.replace(qpos=props.qpos.at[:, :3].set(b.pos), qvel=props.qvel.at[:, :3].set(b.vel))

    def steer(self, goal: JuggleGoal, frame, move, turn) -> JuggleGoal:
        return goal.replace(loc=super().steer(goal.loc, frame, move, turn))

    def markers(self, goal: JuggleGoal, frame) -> dict[str, jax.Array]:
        out = dict(super().markers(goal.loc, frame))
        for i in range(3):
            p = goal.balls.pos[i]
            out[f"ball{i}"] = jnp.stack([p, p])
        return out

    def summary(self, info, alive):
        out = super().summary(info, alive)
        catches = (np.asarray(info["catches"]) * alive).sum()
        misses = (np.asarray(info["misses"]) * alive).sum()
        out["catches_per_throw"] = float(catches / (catches + misses)) if catches + misses else float("nan")
        out["catches"], out["misses"] = int(catches), int(misses)
        throws = (np.asarray(info["throws"]) * alive).sum()
        out["release_speed_error_m_s"] = (
            float((np.asarray(info["release_error"]) * alive).sum() / throws) if throws else float("nan")
        )
        out["longest_streak"] = longest_streak(np.asarray(info["catches"]) * alive, np.asarray(info["misses"]) * alive)
        return out


def longest_streak(catches: np.ndarray, misses: np.ndarray) -> int:
    """Most catches in a row without a miss, over episodes: ``catches``, ``misses`` [T, E] counts."""
    best = 0
    for e in range(catches.shape[1]):
        run = 0
        for c, m in zip(catches[:, e], misses[:, e]):
            if m:
                run = 0
            run += int(c)
            best = max(best, run)
    return best
