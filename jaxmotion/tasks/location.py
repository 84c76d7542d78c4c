"""Goal tasks on the ground plane: target location, target heading, aiming while going to a location.

Target location follows the authors' code (notes §1, ``ICCGANHumanoidTarget``). With p and p'
the root's xy before and after a control step (dt = 1/30 s), d = target - p and T the steps left
on the goal's timer, the wanted speed is s* = min(|d|/dt, clip(|d|/(T dt), lo, hi)), the wanted
velocity v* = s* d/|d|, and the reward r = exp(-3 |v - v*|^2 / s*^2) with v = (p' - p)/dt, or 1
once |target - p'| is inside the radius. The goal features (4) are the unit vector to the target
in the heading frame, the required speed min(|d|/(T dt), hi) and min(|d|/3, 1.5).

Target heading (our definition; the paper's appendix with its formula is not available): the
goal is a direction u and a speed s in the world plane; g = (u in the heading frame (2), s); the
reward is the location reward with the target at infinity along u, r = exp(-3 |v - s u|^2 / s^2).
A new heading (the current facing ± U(0, turn) degrees) and speed come with each timer.

Aiming (notes §1, ``ICCGANHumanoidTargetAiming``): with each location goal comes an aim direction
d*, the horizontal root-to-target direction turned left by U(0, 45°) and up by U(0, 30°). With e
and h the right elbow and hand (the ``right_lower_arm`` and ``right_hand`` bodies) and L = |h - e|,
r_aim = exp(-2 |e + L d* - h| / L); inside the goal radius it is clip(forearm_z / 0.8, 0, 1)
(raise the forearm), and the aim features are zeroed there.
"""

from __future__ import annotations

import dataclasses
from typing import Annotated
import jax
import jax.numpy as jnp
from flax import struct

from jaxmotion.config.checks import Min, NonNegative, Ordered, Positive, Range
from jaxmotion.motion.observations import LinkFrames
from jaxmotion.tasks.base import Task, TaskStep, heading_angle, root_xy, rotate_z, to_heading


@dataclasses.dataclass(frozen=True)
class LocationConfig:
    """Target location (defaults: the authors' walk/crouch settings, notes §1)."""

    radius: Positive = 0.5
    """A goal counts as reached inside this distance (m); the reward is then 1."""
    speed_range: Annotated[tuple[float, float], Min(0), Ordered()] = (1.2, 1.5)
    """Clip of the required speed (m/s) the reward asks for."""
    timer_range: Annotated[tuple[int, int], Min(1), Ordered(strict=True)] = (90, 150)
    """Control steps a goal lasts: U{lo .. hi-1}."""
    v0_mean: float = 1.0
    v0_std: NonNegative = 0.25
    v0_range: Annotated[tuple[float, float], Min(0), Ordered()] = (0.0, 1.25)
    """The goal's distance is v0 * timer / 30 with v0 from this truncated normal (m/s)."""
    sharp_turns: bool = True
    """True: a goal in any direction; False: within ±60 degrees of the current heading."""
    max_overshoot: NonNegative = 3.0
    """End the episode when the distance to the goal has grown by this much (m) since it was set
    (0 disables)."""
    weight: NonNegative = 0.5
    """ω of the location objective."""


@dataclasses.dataclass(frozen=True)
class HeadingConfig:
    """Target heading and speed (the paper gives no formula; ours is in ``tasks/location.py``)."""

    speed_range: Annotated[tuple[float, float], Min(0), Ordered()] = (1.0, 1.5)
    """Target speed, uniform in this range (m/s)."""
    turn_deg: Annotated[float, Range(0, 180)] = 90.0
    """Each new heading is the current facing ± U(0, turn_deg)."""
    timer_range: Annotated[tuple[int, int], Min(1), Ordered(strict=True)] = (90, 150)
    """Control steps a heading lasts: U{lo .. hi-1}."""
    settle_steps: Annotated[int, Min(0)] = 30
    """Metrics skip this many steps after each new heading (time to turn)."""
    weight: NonNegative = 0.5


@dataclasses.dataclass(frozen=True)
class AimConfig:
    """Aiming: the right forearm points along a target direction (notes §1)."""

    yaw_deg: Annotated[tuple[float, float], Range(-180, 180), Ordered()] = (0.0, 45.0)
    """Aim direction: the horizontal root-to-target direction turned left by U(yaw range)..."""
    pitch_deg: Annotated[tuple[float, float], Range(-90, 90), Ordered()] = (0.0, 30.0)
    """... and up by U(pitch range)."""
    weight: NonNegative = 0.25
    """ω of the aim objective."""


_EPS = 1e-6


@struct.dataclass
class LocationGoal:
    target: jax.Array  # [2] world xy
    timer: jax.Array  # int: steps left
    dist0: jax.Array  # distance when the goal was set
    reached: jax.Array  # bool: inside the radius at some step of this goal


def _truncnorm(rng, mean, std, lo, hi):
    return mean + std * jax.random.truncated_normal(rng, (lo - mean) / max(std, _EPS), (hi - mean) / max(std, _EPS))


def _unit(v):
    return v / jnp.maximum(jnp.linalg.norm(v), _EPS)


def velocity_reward(v: jax.Array, v_star: jax.Array, s_star: jax.Array) -> jax.Array:
    """exp(-3 |v - v*|^2 / s*^2), the authors' velocity-matching reward."""
    return jnp.exp(-3.0 * jnp.sum((v - v_star) ** 2) / jnp.maximum(s_star, _EPS) ** 2)


class Location(Task):
    """Walk (run, crouch) to a target location before its timer runs out."""

    settings = (("location", LocationConfig),)

    reward_names = ("location",)

    goal_parts = (("location", 4),)

    def weights(self):
        return (self.cfg.location.weight,)

    def new_goal(self, rng: jax.Array, frame: LinkFrames) -> LocationGoal:
        c = self.cfg.location
        k_t, k_v, k_dir = jax.random.split(rng, 3)
        timer = jax.random.randint(k_t, (), c.timer_range[0], c.timer_range[1])
        v0 = _truncnorm(k_v, c.v0_mean, c.v0_std, *c.v0_range)
        dist = v0 * timer.astype(jnp.float32) * self.env.dt
        if c.sharp_turns:
            ang = jax.random.uniform(k_dir, (), minval=0.0, maxval=2 * jnp.pi)
        else:
            ang = heading_angle(frame) + jax.random.uniform(k_dir, (), minval=-jnp.pi / 3, maxval=jnp.pi / 3)
        target = root_xy(frame) + dist * jnp.stack([jnp.cos(ang), jnp.sin(ang)])
        return LocationGoal(target=target, timer=timer, dist0=dist, reached=jnp.zeros((), bool))

    def init(self, rng, frame, start=None):
        return self.new_goal(rng, frame)

    def observe(self, goal: LocationGoal, frame: LinkFrames) -> jax.Array:
        hi = self.cfg.location.speed_range[1]
        d = goal.target - root_xy(frame)
        dist = jnp.linalg.norm(d)
        u = to_heading(frame, jnp.concatenate([_unit(d), jnp.zeros((1,))]))[:2]
        speed = jnp.minimum(dist / (jnp.maximum(goal.timer, 1) * self.env.dt), hi)
        return jnp.concatenate([u, speed[None], jnp.minimum(dist / 3.0, 1.5)[None]])

    def location_reward(self, goal: LocationGoal, p: jax.Array, p_next: jax.Array) -> jax.Array:
        c, dt = self.cfg.location, self.env.dt
        d = goal.target - p
        dist = jnp.linalg.norm(d)
        s_star = jnp.minimum(dist / dt, jnp.clip(dist / (jnp.maximum(goal.timer, 1) * dt), *c.speed_range))
        r = velocity_reward((p_next - p) / dt, s_star * _unit(d), s_star)
        return jnp.where(jnp.linalg.norm(goal.target - p_next) < c.radius, 1.0, r)

    def step(self, goal: LocationGoal, prev: LinkFrames, frame: LinkFrames, rng, power=None) -> TaskStep:
        c = self.cfg.location
        p, p_next = root_xy(prev), root_xy(frame)
        r = self.location_reward(goal, p, p_next)
        dist = jnp.linalg.norm(goal.target - p_next)
        inside = dist < c.radius
        reached = goal.reached | inside
        timer = goal.timer - 1
        expired = timer <= 0
        fail = (dist - goal.dist0 > c.max_overshoot) if c.max_overshoot > 0 else jnp.zeros((), bool)
        kept = goal.replace(timer=timer, reached=reached)
        nxt = self.new_goal(rng, frame)
        goal = jax.tree.map(lambda a, b: jnp.where(expired, a, b), nxt, kept)
        info = {"distance": dist, "goal_ended": expired, "goal_reached": expired & reached, "inside": inside}
        return TaskStep(goal=goal, rewards=r[None], terminated=fail, info=info)

    def steer(self, goal: LocationGoal, frame, move, turn) -> LocationGoal:
        """The target moves by ``move``; the timer is held at its longest, and the overshoot
        measure restarts from the current distance, so the user's target stays."""
        target = goal.target + move
        return goal.replace(
            target=target,
            timer=jnp.full_like(goal.timer, self.cfg.location.timer_range[1]),
            dist0=jnp.linalg.norm(target - root_xy(frame)),
        )

    def markers(self, goal: LocationGoal, frame) -> dict[str, jax.Array]:
        p = jnp.concatenate([goal.target, jnp.full((1,), 0.1)])  # a ball lying on the floor
        return {"target": jnp.stack([p, p])}

    def summary(self, info, alive):
        ended = (info["goal_ended"] & alive).sum()
        out = {
            "mean_distance_m": float(info["distance"][alive].mean()) if alive.any() else float("nan"),
            "goals_ended": int(ended),
            "success_rate": float((info["goal_reached"] & alive).sum() / ended) if ended else float("nan"),
            "time_inside_radius": float(info["inside"][alive].mean()) if alive.any() else float("nan"),
        }
        return out


@struct.dataclass
class HeadingGoal:
    direction: jax.Array  # [2] unit, world
    speed: jax.Array
    timer: jax.Array
    age: jax.Array  # steps since the heading was set


class Heading(Task):
    """Go along a target heading at a target speed (our definition, see the module docstring)."""

    settings = (("heading", HeadingConfig),)

    reward_names = ("heading",)

    goal_parts = (("heading", 3),)

    def weights(self):
        return (self.cfg.heading.weight,)

    def new_goal(self, rng, frame) -> HeadingGoal:
        c = self.cfg.heading
        k_t, k_s, k_a = jax.random.split(rng, 3)
        turn = jnp.deg2rad(c.turn_deg)
        ang = heading_angle(frame) + jax.random.uniform(k_a, (), minval=-turn, maxval=turn)
        return HeadingGoal(
            direction=jnp.stack([jnp.cos(ang), jnp.sin(ang)]),
            speed=jax.random.uniform(k_s, (), minval=c.speed_range[0], maxval=c.speed_range[1]),
            timer=jax.random.randint(k_t, (), c.timer_range[0], c.timer_range[1]),
            age=jnp.zeros((), jnp.int32),
        )

    def init(self, rng, frame, start=None):
        return self.new_goal(rng, frame)

    def observe(self, goal: HeadingGoal, frame) -> jax.Array:
        u = to_heading(frame, jnp.concatenate([goal.direction, jnp.zeros((1,))]))[:2]
        return jnp.concatenate([u, goal.speed[None]])

    def step(self, goal: HeadingGoal, prev, frame, rng, power=None) -> TaskStep:
        v = (root_xy(frame) - root_xy(prev)) / self.env.dt
        r = velocity_reward(v, goal.speed * goal.direction, goal.speed)
        speed = jnp.linalg.norm(v)
        cos = jnp.sum(v * goal.direction) / jnp.maximum(speed, _EPS)
        err_deg = jnp.rad2deg(jnp.arccos(jnp.clip(cos, -1.0, 1.0)))
        info = {
            "heading_error_deg": err_deg,
            "speed_error": jnp.abs(speed - goal.speed),
            "settled": goal.age >= self.cfg.heading.settle_steps,
        }
        kept = goal.replace(timer=goal.timer - 1, age=goal.age + 1)
        goal = jax.tree.map(lambda a, b: jnp.where(kept.timer <= 0, a, b), self.new_goal(rng, frame), kept)
        return TaskStep(goal=goal, rewards=r[None], terminated=jnp.zeros((), bool), info=info)

    def steer(self, goal: HeadingGoal, frame, move, turn) -> HeadingGoal:
        """``turn`` turns the heading; ``move`` along the heading changes the speed (within the
        trained range)."""
        lo, hi = self.cfg.heading.speed_range
        speed = jnp.clip(goal.speed + jnp.sum(move * goal.direction), lo, hi)
        return goal.replace(
            direction=rotate_z(goal.direction, turn),
            speed=speed,
            timer=jnp.full_like(goal.timer, self.cfg.heading.timer_range[1]),
        )

    def markers(self, goal: HeadingGoal, frame) -> dict[str, jax.Array]:
        """A blue arrow on the floor from the root along the heading, 0.5 s of the target speed long."""
        p = jnp.concatenate([root_xy(frame), jnp.full((1,), 0.05)])
        d = jnp.concatenate([0.5 * goal.speed * goal.direction, jnp.zeros((1,))])
        return {"heading": jnp.stack([p, p + d])}

    def summary(self, info, alive):
        m = alive & info["settled"]
        if not m.any():
            return {"heading_error_deg": float("nan"), "speed_error_m_s": float("nan")}
        return {
            "heading_error_deg": float(info["heading_error_deg"][m].mean()),
            "speed_error_m_s": float(info["speed_error"][m].mean()),
        }


@struct.dataclass
class AimGoal:
    loc: LocationGoal
    aim: jax.Array  # [3] unit, world


class AimLocation(Location):
    """Go to a location while pointing the right forearm along a target direction."""

    settings = (("location", LocationConfig), ("aim", AimConfig))

    reward_names = ("location", "aim")

    def __init__(self, cfg, env):
        super().__init__(cfg, env)
        ch = env.character
        self._elbow, self._hand = ch.body_index("right_lower_arm"), ch.body_index("right_hand")

    goal_parts = (("location", 4), ("aim", 3))

    def weights(self):
        return (self.cfg.location.weight, self.cfg.aim.weight)

    def new_aim(self, rng, loc: LocationGoal, frame) -> jax.Array:
        c = self.cfg.aim
        k_y, k_p = jax.random.split(rng)
        d = loc.target - root_xy(frame)
        yaw = jnp.arctan2(d[1], d[0]) + jnp.deg2rad(
            jax.random.uniform(k_y, (), minval=c.yaw_deg[0], maxval=c.yaw_deg[1])
        )
        pitch = jnp.deg2rad(jax.random.uniform(k_p, (), minval=c.pitch_deg[0], maxval=c.pitch_deg[1]))
        return jnp.stack([jnp.cos(pitch) * jnp.cos(yaw), jnp.cos(pitch) * jnp.sin(yaw), jnp.sin(pitch)])

    def init(self, rng, frame, start=None):
        k_l, k_a = jax.random.split(rng)
        loc = self.new_goal(k_l, frame)
        return AimGoal(loc=loc, aim=self.new_aim(k_a, loc, frame))

    def _inside(self, goal: AimGoal, frame) -> jax.Array:
        return jnp.linalg.norm(goal.loc.target - root_xy(frame)) < self.cfg.location.radius

    def observe(self, goal: AimGoal, frame) -> jax.Array:
        aim = jnp.where(self._inside(goal, frame), 0.0, to_heading(frame, goal.aim))
        return jnp.concatenate([super().observe(goal.loc, frame), aim])

    def aim_reward(self, aim: jax.Array, frame: LinkFrames, inside: jax.Array) -> tuple[jax.Array, jax.Array]:
        """(reward, angle between forearm and aim direction in degrees)."""
        e, h = frame.pos[self._elbow], frame.pos[self._hand]
        L = jnp.maximum(jnp.linalg.norm(h - e), _EPS)
        r = jnp.exp(-2.0 * jnp.linalg.norm(e + L * aim - h) / L)
        fore = (h - e) / L
        r = jnp.where(inside, jnp.clip(fore[2] / 0.8, 0.0, 1.0), r)
        ang = jnp.rad2deg(jnp.arccos(jnp.clip(jnp.sum(fore * aim), -1.0, 1.0)))
        return r, ang

    def step(self, goal: AimGoal, prev, frame, rng, power=None) -> TaskStep:
        k_l, k_a = jax.random.split(rng)
        inside = self._inside(goal, frame)
        r_aim, ang = self.aim_reward(goal.aim, frame, inside)
        loc = super().step(goal.loc, prev, frame, k_l)
        aim = jnp.where(loc.info["goal_ended"], self.new_aim(k_a, loc.goal, frame), goal.aim)
        info = dict(loc.info, aim_error_deg=ang, aiming=~inside)
        return TaskStep(
            goal=AimGoal(loc=loc.goal, aim=aim),
            rewards=jnp.concatenate([loc.rewards, r_aim[None]]),
            terminated=loc.terminated,
            info=info,
        )

    def steer(self, goal: AimGoal, frame, move, turn) -> AimGoal:
        return AimGoal(loc=super().steer(goal.loc, frame, move, turn), aim=rotate_z(goal.aim, turn))

    def markers(self, goal: AimGoal, frame) -> dict[str, jax.Array]:
        h = frame.pos[self._hand]
        return dict(super().markers(goal.loc, frame), aim=jnp.stack([h, h + 0.6 * goal.aim]))

    def summary(self, info, alive):
        out = super().summary(info, alive)
        m = alive & info["aiming"]
        out["aim_error_deg"] = float(info["aim_error_deg"][m].mean()) if m.any() else float("nan")
        return out
