"""Tennis swing (paper §6.1, §6.4): hit a fed ball with the racket; our formula (the paper's is in
an appendix we do not have, and the authors' code has no tennis).

The scene holds the sword-and-shield character with a racket in the sword's place
(``PhysicsConfig.racket``) and one free ball (``PhysicsConfig.props``; ``physics/props.py``):
it bounces off the racket head and the floor and passes through the body. Every ``feed_every``
control steps (and at reset) the task puts the ball beside the character, on its racket side,
tossed gently upwards, and draws a landing target 8-12 m ahead (``TennisConfig``).

* **Hit**: the first control step whose racket-head contact force on the ball reaches
  ``touch_force``. When that contact ends, the ball's velocity is its outgoing velocity: the
  hit reward, paid once then, is 0.5 min(|v| / v*, 1) + 0.5 exp(-d^2 / 2 sigma^2), d the distance
  from where the ball would land (free flight to the floor) to the target.
* **Reach** (our shaping, ``reach_weight``; 0 for outcome only): exp(-4 d^2) with d the racket
  head's distance to the ball until it is hit, 1 after.
* **Goal features** (10, raw): the ball's position from the root's ground point and its velocity,
  in the heading frame (6); the target from the root's ground point in the heading frame, / 10
  (2); the time since the feed / ``feed_every`` (1); whether the ball has been hit (1).
* **Metrics** (``eval``): hit rate (balls hit / balls fed), outgoing speed and landing error of
  the hits, the racket's closest approach to unhit balls.
"""

from __future__ import annotations

import dataclasses
from typing import Annotated
import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from jaxmotion.config.checks import Count, Min, NonNegative, Ordered, Positive
from jaxmotion.motion import rotations as R
from jaxmotion.physics.character import RACKET_HEAD
from jaxmotion.physics.props import Props
from jaxmotion.tasks.base import Task, TaskStep, heading_angle, root_xy, rotate_z, to_heading


@dataclasses.dataclass(frozen=True)
class TennisConfig:
    """Tennis swing (``tasks/tennis.py``; the paper's formula is in an appendix we do not have,
    so this one is ours): a ball is fed beside the character every ``feed_every`` steps; hitting
    it pays for its outgoing speed and for where it would land."""

    feed_every: Count = 60
    """Control steps between balls (60: 2 s)."""
    feed_forward: Annotated[tuple[float, float], Ordered()] = (0.55, 0.85)
    feed_right: Annotated[tuple[float, float], Ordered()] = (0.35, 0.65)
    feed_height: Annotated[tuple[float, float], Min(0), Ordered()] = (0.9, 1.3)
    """Where a ball appears, from the root's ground point in its heading frame (m): ahead, to the
    right (the racket side), above the floor; uniform in each range."""
    feed_up_speed: Annotated[tuple[float, float], Ordered()] = (0.5, 1.5)
    """Its vertical speed upwards (m/s), as if tossed; no horizontal speed."""
    target_ahead: Annotated[tuple[float, float], Ordered()] = (8.0, 12.0)
    target_side: Annotated[tuple[float, float], Ordered()] = (-2.0, 2.0)
    """The landing target, drawn with each ball: ahead and to the left (m) in the heading frame."""
    target_speed: Positive = 10.0
    """Outgoing speed that earns the full speed half of the hit reward (m/s)."""
    landing_sigma: Positive = 2.0
    """Landing half of the hit reward: exp(-d^2 / (2 sigma^2)), d the landing error (m)."""
    touch_force: NonNegative = 1.0
    """A racket contact of at least this normal force (N) is a hit."""
    weight: NonNegative = 0.35
    """ω of the hit reward."""
    reach_weight: NonNegative = 0.15
    """ω of the reach reward exp(-4 d^2), d the racket head's distance to the ball before it is
    hit (our shaping; 0 leaves the paper's outcome-only reward)."""


G = 9.81


@struct.dataclass
class TennisGoal:
    t: jax.Array  # control steps since the ball was fed
    target: jax.Array  # [2] world xy of the landing target
    ball_pos: jax.Array  # [3] the ball as last sensed (or just placed)
    ball_vel: jax.Array  # [3]
    force: jax.Array  # racket contact force on the ball over the last step (N)
    hit: jax.Array  # bool: hit since it was fed
    paid: jax.Array  # bool: its hit has been scored
    feed: jax.Array  # bool: the ball is to be placed at ball_pos / ball_vel before the next step


def landing_point(pos: jax.Array, vel: jax.Array, radius: float) -> jax.Array:
    """Where a ball at ``pos`` [3] with velocity ``vel`` [3] meets the floor in free flight ([2] xy;
    its centre at height ``radius``)."""
    h = jnp.maximum(pos[2] - radius, 0.0)
    t = (vel[2] + jnp.sqrt(vel[2] ** 2 + 2 * G * h)) / G
    return pos[:2] + vel[:2] * t


def hit_reward(vel: jax.Array, landing: jax.Array, target: jax.Array, v_star: float, sigma: float) -> jax.Array:
    """0.5 min(|v| / v*, 1) + 0.5 exp(-|landing - target|^2 / 2 sigma^2)."""
    speed = jnp.linalg.norm(vel)
    d2 = jnp.sum((landing - target) ** 2)
    return 0.5 * jnp.minimum(speed / v_star, 1.0) + 0.5 * jnp.exp(-d2 / (2 * sigma**2))


class Tennis(Task):
    """Hit a fed ball with the racket towards a landing target."""

    settings = (("tennis", TennisConfig),)

    reward_names = ("hit", "reach")
    goal_parts = (("tennis", 10),)
    min_reward = 0.0

    def __init__(self, cfg, env):
        super().__init__(cfg, env)
        pc = env.cfg.physics
        if not (pc.racket and len(pc.props) == 1):
            raise ValueError(
                "the tennis task needs a racket and one ball in the scene: "
                "env.physics.sword_shield=true, racket=true, props=(PropConfig(),)"
            )
        if pc.sim_hz < 240:
            raise ValueError(
                f"the tennis ball passes through the racket at {pc.sim_hz:g} Hz "
                "(physics/props.py): set env.physics.sim_hz=240 or more"
            )
        self._racket = env.character.body_index("sword")
        self._radius = pc.props[0].radius

    def weights(self):
        return (self.cfg.tennis.weight, self.cfg.tennis.reach_weight)

    def head(self, frame) -> jax.Array:
        """World position of the racket head's centre."""
        return frame.pos[self._racket] + R.quat_rotate(frame.quat[self._racket], jnp.asarray(RACKET_HEAD, jnp.float32))

    def _feed(self, rng, frame) -> tuple[jax.Array, jax.Array, jax.Array]:
        """A new ball (position, velocity) beside the character and a landing target."""
        c = self.cfg.tennis
        k = jax.random.split(rng, 6)
        u = lambda key, lo_hi: jax.random.uniform(key, (), minval=lo_hi[0], maxval=lo_hi[1])
        yaw = heading_angle(frame)
        ground = root_xy(frame)
        rel = rotate_z(jnp.stack([u(k[0], c.feed_forward), -u(k[1], c.feed_right)]), yaw)
        pos = jnp.concatenate([ground + rel, u(k[2], c.feed_height)[None]])
        vel = jnp.stack([0.0, 0.0, u(k[3], c.feed_up_speed)])
        target = ground + rotate_z(jnp.stack([u(k[4], c.target_ahead), u(k[5], c.target_side)]), yaw)
        return pos, vel, target

    def init(self, rng, frame, start=None) -> TennisGoal:
        pos, vel, target = self._feed(rng, frame)
        f = jnp.zeros((), bool)
        return TennisGoal(
            t=jnp.zeros((), jnp.int32),
            target=target,
            ball_pos=pos,
            ball_vel=vel,
            force=jnp.zeros(()),
            hit=f,
            paid=f,
            feed=jnp.ones((), bool),
        )

    def sense(self, goal: TennisGoal, props: Props) -> TennisGoal:
        return goal.replace(
            ball_pos=props.qpos[0, :3],
            ball_vel=props.qvel[0, :3],
            force=props.force[0] if props.force.shape[0] else jnp.zeros(()),
        )

    def place(self, goal: TennisGoal, props: Props) -> Props:
        qpos = jnp.concatenate([goal.ball_pos, jnp.asarray([1.0, 0.0, 0.0, 0.0])])
        qvel = jnp.concatenate([goal.ball_vel, jnp.zeros(3)])
        return props.replace(
            qpos=jnp.where(goal.feed, qpos[None], props.qpos), qvel=jnp.where(goal.feed, qvel[None], props.qvel)
        )

    def observe(self, goal: TennisGoal, frame) -> jax.Array:
        ground = jnp.concatenate([root_xy(frame), jnp.zeros((1,))])
        target = to_heading(frame, jnp.concatenate([goal.target, jnp.zeros(1)]) - ground)[:2] / 10.0
        phase = goal.t.astype(jnp.float32) / self.cfg.tennis.feed_every
        return jnp.concatenate(
            [
                to_heading(frame, goal.ball_pos - ground),
                to_heading(frame, goal.ball_vel),
                target,
                phase[None],
                goal.hit.astype(jnp.float32)[None],
            ]
        )

    def step(self, goal: TennisGoal, prev, frame, rng, power=None) -> TaskStep:
        c = self.cfg.tennis
        touching = goal.force >= c.touch_force
        hit = goal.hit | touching
        released = hit & ~goal.paid & ~touching
        landing = landing_point(goal.ball_pos, goal.ball_vel, self._radius)
        r_hit = jnp.where(
            released, hit_reward(goal.ball_vel, landing, goal.target, c.target_speed, c.landing_sigma), 0.0
        )
        reach_d = jnp.linalg.norm(self.head(frame) - goal.ball_pos)
        r_reach = jnp.where(hit, 1.0, jnp.exp(-4.0 * reach_d**2))
        t = goal.t + 1
        fed = t >= c.feed_every
        pos, vel, target = self._feed(rng, frame)
        nxt = TennisGoal(
            t=jnp.where(fed, 0, t),
            target=jnp.where(fed, target, goal.target),
            ball_pos=jnp.where(fed, pos, goal.ball_pos),
            ball_vel=jnp.where(fed, vel, goal.ball_vel),
            force=goal.force,
            hit=hit & ~fed,
            paid=(goal.paid | released) & ~fed,
            feed=fed,
        )
        speed = jnp.linalg.norm(goal.ball_vel)
        # Each ball is counted when its feed_every steps are over: fed, and hit or not.
        info = dict(
            fed=fed.astype(jnp.float32),
            hits=(fed & hit).astype(jnp.float32),
            released=released.astype(jnp.float32),
            out_speed=jnp.where(released, speed, 0.0),
            landing_error=jnp.where(released, jnp.linalg.norm(landing - goal.target), 0.0),
            reach_m=jnp.where(hit, 0.0, reach_d),
            unhit=(~hit).astype(jnp.float32),
        )
        return TaskStep(goal=nxt, rewards=jnp.stack([r_hit, r_reach]), terminated=jnp.zeros((), bool), info=info)

    def summary(self, info, alive):
        a = np.asarray(alive, np.float64)
        total = lambda k: float((np.asarray(info[k]) * a).sum())
        fed, hits, rel = total("fed"), total("hits"), total("released")
        # Balls whose feed_every steps ran out within the episode (the last one may not have).
        out = {
            "balls": int(fed),
            "hits": int(hits),
            "hit_rate": hits / fed if fed else float("nan"),
            "out_speed_m_s": total("out_speed") / rel if rel else float("nan"),
            "landing_error_m": total("landing_error") / rel if rel else float("nan"),
        }
        unhit = np.asarray(info["unhit"]) * a
        out["reach_m"] = (
            float((np.asarray(info["reach_m"]) * unhit).sum() / unhit.sum()) if unhit.sum() else float("nan")
        )
        return out

    def markers(self, goal: TennisGoal, frame) -> dict[str, jax.Array]:
        tgt = jnp.concatenate([goal.target, jnp.zeros(1)])
        return {"ball": jnp.stack([goal.ball_pos, goal.ball_pos]), "target": jnp.stack([tgt, tgt])}
