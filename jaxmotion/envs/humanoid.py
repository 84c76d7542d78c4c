"""The humanoid scene: reference-state init, PD control, falls, discriminator views, and a task.

Physics runs on the backend ``cfg.physics.backend`` names (``physics/backends.py``: MJX, or MuJoCo
C inside the compiled loop); observations are computed in JAX from ``qpos``/``qvel`` either way.

``HumanoidEnv(cfg)`` holds static things (MJX model, motion libraries, index arrays); its
``reset(rng)`` and ``step(state, action)`` are pure functions of an ``EnvState`` pytree, made to be
vmapped over environments and scanned over time. ``step`` resets an environment that terminated
or timed out (the reset state comes back in ``state``; the pre-reset observation is kept in
``StepOut.final_obs`` for bootstrapping), and an environment whose physics went non-finite is
reset without its NaNs reaching the batch. The task (``EnvConfig.task``, see ``tasks/``) adds its
goal state to ``EnvState.goal``, its goal features after the body state in the observation, its
rewards to ``StepOut.task_reward`` and may end an episode. Props (balls, ``physics/props.py``)
follow the character in the physics state; the task reads them after each step and places them
before the next (``Task.sense``/``Task.place``).
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Annotated, Any, Literal
from collections.abc import Sequence

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
from flax import struct
from mujoco import mjx

from jaxmotion.config.checks import AllowInf, Min, NonEmpty, Ordered, Problem, validate
from jaxmotion.config.errors import ConfigError
from jaxmotion.motion import observations as O
from jaxmotion.motion.groups import default_groups, group_indices, resolve_group
from jaxmotion.motion.motionlib import (
    MotionLib,
    load_motionlib,
    reweighted,
    qpos_of,
    qpos_qvel,
    sample,
    sample_times,
    sample_windows,
)
from jaxmotion.physics import sim
from jaxmotion.physics.arena import SPORTS, ArenaConfig
from jaxmotion.physics.fk import LinkFK
from jaxmotion.physics.props import Props
from jaxmotion.physics.character import character
from jaxmotion.tasks import TASKS, TaskConfig, make_task


@dataclasses.dataclass(frozen=True)
class GroupConfig:
    """A body group with its own discriminator and reference clips."""

    name: Annotated[str, NonEmpty()] = "full"
    """A default group (upper, lower, arms, rest, full) or a new name with ``links`` given."""
    motions: tuple[str, ...] = ()
    """Reference clips (files or folders, relative to the data directory) for this group."""
    links: tuple[str, ...] = ()
    """Link names; empty means the default group of that name."""
    anchor: Annotated[str, NonEmpty()] = "default"
    """Link the observation is expressed against; 'heading' for the heading frame; 'default'
    for the default group's anchor."""
    frames: Annotated[int, Min(2)] = 5
    """Window length n+2 frames: t-n ... t+1."""
    speed_range: Annotated[tuple[float, float], Min(0, open=True), Ordered()] = (1.0, 1.0)
    """Random replay-speed range of the reference windows (the paper uses (0.8, 1.2) for some)."""
    weight: Annotated[float, Min(0)] | None = None
    """ω of this group's objective; None shares what the given weights leave (``tasks.combine_weights``)."""


@dataclasses.dataclass(frozen=True)
class EnvConfig:
    """The imitation environment."""

    physics: sim.PhysicsConfig = sim.PhysicsConfig()
    init_motions: tuple[str, ...] = ()
    """Clips for reference-state initialisation; empty means the first group's clips."""
    groups: tuple[GroupConfig, ...] = (GroupConfig(),)
    episode_steps: Annotated[int, Min(1)] = 300
    """Episode time limit in control steps (300 = 10 s at 30 Hz)."""
    policy_frames: Annotated[int, Min(1)] = 4
    """Frames of link state in the policy observation (current plus history). The paper asks
    for at least the discriminators' history (t-3 ... t); the authors' code uses 4."""
    early_termination: bool = True
    """End the episode when a body other than the feet touches the ground."""
    fall_height: Annotated[float, Min(0)] = 0.0
    """0: a ground contact of any body but the feet is a fall. > 0: only while that body's
    origin is below this height (the authors' code: 0.15 m, with contact force > 1 N), so a hand
    or a knee may touch the ground while its link stays up."""
    contact_grace_steps: Annotated[int, Min(0)] = 2
    """Steps after reset in which ground contact does not end the episode."""
    allowed_contacts: tuple[str, ...] = ("right_foot", "left_foot")
    action_scale: Annotated[float, Min(0, open=True)] = 2.0
    """PD target = mid-range + action_scale * action * half-range. 2.0 is the authors' code
    (mid + action * full range: ±0.5 reaches the limits); 1.0 reaches them at ±1."""
    init_above_ground: bool = True
    """Lift a reference-state initialisation whose lowest geom would start inside the floor."""
    init_within_limits: bool = True
    """Clamp the reference-state initialisation's joint angles to the joint ranges."""
    ref_within_limits: bool = True
    """Clamp the joint angles of the discriminators' reference windows to the joint ranges, so
    every reference pose is one the simulated character can show. The shared squat leaves the
    hip and knee ranges by up to 17 degrees in 61% of its frames; unclamped, those frames are
    a feature no policy can match."""
    level_feet: tuple[str, ...] = ()
    """Clips (file stems or path endings) whose reference is levelled where both feet are
    planted: the body tilted a few degrees about the root so that both soles rest on the floor
    (``motion/level.py``). For clips retargeted onto uneven feet, like the shared squat."""
    max_qvel: Annotated[float, Min(0, open=True), AllowInf()] = 100.0
    """|qvel| above this counts as unstable physics: the environment is reset (inf: never)."""
    task: TaskConfig = TaskConfig()
    """The task the character performs besides imitating (``tasks/``); 'imitate' for none."""
    init_sampling: Literal["duration", "uniform"] = "duration"
    """How a reset picks its clip from ``init_motions``: 'duration' (in proportion to each clip's
    length, so every moment of the data is equally likely) or 'uniform' (each clip alike, as
    the PHC authors' motion library, so short clips are not starved)."""
    drop_props: bool = False
    """Load sword-and-shield clips (17 bodies) onto the 15-body humanoid by dropping the sword,
    the shield and the right wrist (``motion.clip.drop_sword_shield``)."""
    players: Literal[1, 2] = 1
    """1: one character (``HumanoidEnv``); 2: two players in the arena (``envs/bout.py``)."""
    arena: ArenaConfig = ArenaConfig()
    """The two-player scene (ring or piste; ``physics/arena.py``); unused with one player."""

    def checks(self) -> list[Problem]:
        """The rules between the scene's settings (``config.checks``): its players, groups, task,
        arena and props."""
        task = TASKS[self.task.name]
        out = self._one_player(task) if self.players == 1 else self._two_players(task)
        defaults = default_groups(character(self.physics.sword_shield))
        for i, g in enumerate(self.groups):
            if not g.links and g.name not in defaults:
                out.append(
                    Problem(f"groups[{i}].name", f"is not a default group ({', '.join(defaults)}) and gives no links")
                )
        return out + self._task_props()

    def _one_player(self, task) -> list[Problem]:
        out = [Problem("groups", "must not be empty: a one-player scene needs a body group")] if not self.groups else []
        if getattr(task, "two_player", False):
            out.append(Problem("task.name", "is a two-player task: it needs env.players=2"))
        return out

    def _two_players(self, task) -> list[Problem]:
        out, sport = [], self.arena.sport
        if self.groups:
            out.append(Problem("groups", "must be empty: two-player scenes have no imitation discriminators yet"))
        if not self.init_motions:
            out.append(
                Problem("init_motions", "must not be empty: a two-player scene needs the clips its players start from")
            )
        if self.physics.sword_shield != SPORTS[sport].sword_shield:
            want = str(SPORTS[sport].sword_shield).lower()
            out.append(Problem("physics.sword_shield", f"the {sport} arena needs env.physics.sword_shield={want}"))
        if not getattr(task, "two_player", False):
            out.append(Problem("task.name", "is not a two-player task (boxing, fencing)"))
        elif task.sport != sport:
            out.append(Problem("arena.sport", f"task {self.task.name!r} needs env.arena.sport={task.sport}"))
        return out

    def _task_props(self) -> list[Problem]:
        """The props and rates the ball tasks need (``tasks/tennis.py``, ``tasks/juggle.py``)."""
        pc, name = self.physics, self.task.name
        if name == "tennis" and not (pc.racket and len(pc.props) == 1):
            return [
                Problem(
                    "task.name",
                    "the tennis task needs a racket and one ball in the scene: "
                    "env.physics.sword_shield=true, racket=true, props=(PropConfig(),)",
                )
            ]
        if name == "tennis" and pc.sim_hz < 240:
            return [
                Problem("physics.sim_hz", "the tennis ball passes through the racket below 240 Hz (physics/props.py)")
            ]
        if name == "juggle+location" and len(pc.props) not in (0, 3):
            return [Problem("physics.props", "juggling needs three balls in the scene or none")]
        return []


@struct.dataclass
class EnvState:
    """One environment's state. ``hist`` holds the last link frames, oldest first; ``goal`` is
    the task's goal state."""

    data: mjx.Data
    hist: O.LinkFrames
    steps: jax.Array
    rng: jax.Array
    goal: Any = None


@struct.dataclass
class StepOut:
    """What a control step reports. Observations are already flat vectors.

    Attributes:
      obs: [obs_dim] policy observation of the returned state (after an automatic reset).
      final_obs: [obs_dim] policy observation reached by this step (before any reset).
      disc_obs: per group [disc_dim_g], the window t-n ... t+1 ending at the reached state.
      terminated: fell or unstable (no bootstrap); truncated: hit the time limit (bootstrap).
      unstable: the physics went non-finite or too fast and was reset.
      task_reward: [len(task.reward_names)] the task's rewards for this step.
      info: the task's per-step metric scalars (``Task.summary``).
    """

    obs: jax.Array
    final_obs: jax.Array
    disc_obs: tuple[jax.Array, ...]
    terminated: jax.Array
    truncated: jax.Array
    unstable: jax.Array
    task_reward: jax.Array
    info: dict


class HumanoidEnv:
    """Pure-functional humanoid imitation environment (see module docstring)."""

    def __init__(
        self,
        cfg: EnvConfig,
        motion_libs: Sequence[MotionLib] | None = None,
        init_lib: MotionLib | None = None,
        physics=None,
    ):
        """``physics`` replaces the backend that ``cfg.physics`` names (e.g. one with other gains)."""
        self.cfg = validate(cfg, "env")
        self.character = character(cfg.physics.sword_shield)
        self.model = sim.mjx_model(cfg.physics)
        self.physics = sim.physics(cfg.physics) if physics is None else physics
        ch = self.character
        self.groups = []
        defaults = default_groups(ch)
        for g in cfg.groups:
            if g.links:
                links = g.links
            elif g.name in defaults:
                links = defaults[g.name].links
            else:  # EnvConfig.checks found this already
                raise ConfigError(
                    f"env.groups: {g.name!r} is not a default group ({sorted(defaults)}) and gives no links"
                )
            if g.anchor == "default":
                anchor = defaults[g.name].anchor if g.name in defaults else None
            else:
                anchor = None if g.anchor == "heading" else g.anchor
            self.groups.append(resolve_group({"name": g.name, "links": links, "anchor": anchor}, ch))
        self.group_idx = [group_indices(g, ch) for g in self.groups]
        if motion_libs is None:
            motion_libs = [
                load_motionlib(g.motions, ch, drop_props=cfg.drop_props, level=cfg.level_feet) for g in cfg.groups
            ]
        self.motion_libs = tuple(motion_libs)
        if init_lib is None:
            init_lib = (
                load_motionlib(cfg.init_motions, ch, drop_props=cfg.drop_props, level=cfg.level_feet)
                if cfg.init_motions
                else self.motion_libs[0]
            )
        self.init_lib = reweighted(init_lib, cfg.init_sampling)
        names = {n for lib in (*self.motion_libs, init_lib) for n in (*lib.clip_names, *lib.clip_paths)}
        unknown = [p for p in cfg.level_feet if not any(n == p or n.endswith(p) for n in names)]
        if unknown:
            raise ConfigError(f"env.level_feet={','.join(unknown)}: names clips that are not loaded")
        self.hist_len = max([cfg.policy_frames] + [g.frames for g in cfg.groups])
        self._mid, self._half, self._lo, self._hi, self._bad_body = joint_arrays(ch, cfg.allowed_contacts)
        self._data0 = mjx.make_data(self.model)
        # The character's own model: link frames, geoms and sizes; props follow it in the scene.
        m = mujoco.MjModel.from_xml_string(sim.character_xml(cfg.physics))
        self._nq, self._nv, self._nb = m.nq, m.nv, m.nbody - 1
        self.num_props = len(cfg.physics.props)
        self._fk = LinkFK(m)
        geoms = [g for g in range(m.ngeom) if m.geom_bodyid[g] != 0 and m.geom_type[g] in (2, 3, 6)]
        self._body_geoms = np.asarray(geoms)
        self._geom_size = jnp.asarray(m.geom_size[geoms], jnp.float32)
        self._geom_type = jnp.asarray(m.geom_type[geoms], jnp.int32)
        self.task = make_task(cfg.task, self)

    # ---- sizes -------------------------------------------------------------------------
    @property
    def action_size(self) -> int:
        return self.character.num_dof

    @property
    def body_obs_size(self) -> int:
        """Size of the body-state part of the observation (normalised); the goal follows it."""
        return self.cfg.policy_frames * self.character.num_bodies * 15

    @property
    def obs_size(self) -> int:
        return self.body_obs_size + self.task.goal_size

    def disc_obs_sizes(self) -> tuple[int, ...]:
        return tuple(g.frames * len(idx[0]) * 9 for g, idx in zip(self.cfg.groups, self.group_idx))

    @property
    def dt(self) -> float:
        return self.cfg.physics.control_dt

    # ---- reset -------------------------------------------------------------------------
    def reset(self, rng: jax.Array, clip_weight: jax.Array | None = None) -> tuple[EnvState, jax.Array]:
        """Reference-state initialisation at a random clip time; history from the clip's past.
        ``clip_weight`` [C] replaces the init clips' probabilities (hard-negative mining)."""
        rng, k = jax.random.split(rng)
        lib = self.init_lib if clip_weight is None else self.init_lib.replace(clip_weight=clip_weight)
        clip, t = sample_times(lib, k, 1)
        return self.reset_at(rng, clip[0], t[0])

    def reset_at(self, rng: jax.Array, clip: jax.Array, t: jax.Array) -> tuple[EnvState, jax.Array]:
        """Reference-state initialisation at time ``t`` (s) of init clip ``clip``."""
        rng, k_goal = jax.random.split(rng)
        qpos_h, qvel_h, start = self.start_window(k_goal, clip, t)
        data = self._data0.replace(
            qpos=self._data0.qpos.at[: self._nq].set(qpos_h[-1]), qvel=self._data0.qvel.at[: self._nv].set(qvel_h[-1])
        )
        # The history is what the simulator's kinematics make of the reference poses, so the first
        # windows after a reset are built exactly like every later one.
        hist = self.frames_of(qpos_h, qvel_h)
        goal = self.task.init(k_goal, _last(hist), start)
        data = self.place_props(data, goal)
        state = EnvState(data=data, hist=hist, steps=jnp.zeros((), jnp.int32), rng=rng, goal=goal)
        return state, self.policy_obs(state)

    def start_window(self, k_goal: jax.Array, clip: jax.Array, t: jax.Array) -> tuple[jax.Array, jax.Array, tuple]:
        """(qpos [H, nq], qvel [H, nv], the task's start) of ``reset_at``'s start: the reference
        window ending at time ``t`` of init clip ``clip`` as the character starts it (oldest first;
        ``k_goal``: the reset's goal key). An exported policy starts from its last frames."""
        times = t - self.dt * jnp.arange(self.hist_len - 1, -1, -1, dtype=jnp.float32)
        ms = sample(self.init_lib, jnp.full_like(times, clip, dtype=jnp.int32), times)
        qpos_h, qvel_h = qpos_qvel(ms)
        if self.cfg.init_within_limits:
            # Some clips leave the joint ranges (the squat's right hip by up to 75 degrees); started
            # there, the limit constraint throws the character (10-20% of resets were unstable).
            qpos_h = self.within_limits(qpos_h)
        if self.cfg.init_above_ground:
            # Lift the whole window so the lowest body geom of the start pose is not in the floor
            # (clamped joints or a clip made for another skeleton can put a foot 10 cm deep).
            lift = jnp.maximum(-self.lowest_point(qpos_h[-1]), 0.0)
            qpos_h = qpos_h.at[..., 2].add(lift)
        # The task may move or replace the start (the tracker's fallen and far starts); its key is
        # derived from the goal's so that tasks that leave the start alone draw what they always did.
        return self.task.start_pose(jax.random.fold_in(k_goal, 1), qpos_h, qvel_h, (clip, t))

    # ---- observations ------------------------------------------------------------------
    def policy_obs(self, state: EnvState) -> jax.Array:
        h = jax.tree.map(lambda x: x[-self.cfg.policy_frames :], state.hist)
        return jnp.concatenate([O.policy_obs(h), self.task.observe(state.goal, _last(state.hist))])

    def disc_obs(self, hist: O.LinkFrames) -> tuple[jax.Array, ...]:
        """Per group, the discriminator view of the newest ``frames`` link frames."""
        out = []
        for g, (links, anchor) in zip(self.cfg.groups, self.group_idx):
            out.append(O.disc_obs(hist.pos[-g.frames :], hist.quat[-g.frames :], links, int(anchor)))
        return tuple(out)

    def ref_disc_obs(self, rng: jax.Array, n: int) -> tuple[jax.Array, ...]:
        """Per group, ``n`` reference windows from that group's clips: [n, disc_dim_g] each."""
        out = []
        keys = jax.random.split(rng, len(self.groups))
        for k, g, lib, (links, anchor) in zip(keys, self.cfg.groups, self.motion_libs, self.group_idx):
            w = sample_windows(lib, k, n, g.frames, self.dt, g.speed_range, pose_only=True)
            # Link poses by forward kinematics of the interpolated joint angles: the poses the
            # simulator would show for them. Blending the clip's link positions and rotations
            # separately bends rigid offsets (the torso's in the pelvis frame) by ~1e-5, which a
            # discriminator can learn to tell from simulated frames.
            qpos = qpos_of(w)
            if self.cfg.ref_within_limits:
                qpos = self.within_limits(qpos)
            pos, quat = self.poses_of(qpos)
            out.append(jax.vmap(functools.partial(O.disc_obs, links=links, anchor=int(anchor)))(pos, quat))
        return tuple(out)

    def within_limits(self, qpos: jax.Array) -> jax.Array:
        """``qpos`` [..., nq] with the joint angles clamped to the joint ranges (root untouched)."""
        return qpos.at[..., 7:].set(self.clip_dof(qpos[..., 7:]))

    def clip_dof(self, dof: jax.Array) -> jax.Array:
        """Joint angles [..., n_dof] clamped to the joint ranges."""
        return jnp.clip(dof, self._lo, self._hi)

    def lowest_point(self, qpos: jax.Array) -> jax.Array:
        """Height of the lowest point of the character's spheres, capsules and boxes at ``qpos``."""
        return lowest_point(*self._fk.geom_frames(qpos, self._body_geoms), self._geom_size, self._geom_type)

    def poses_of(self, qpos: jax.Array) -> tuple[jax.Array, jax.Array]:
        """Link positions [..., nb, 3] and orientations [..., nb, 4] of generalised positions
        [..., nq]: ``mjx.kinematics``' ``xpos``/``xquat`` by the lean tree walk of ``physics/fk.py``."""
        return self._fk(qpos)

    def frames_of(self, qpos: jax.Array, qvel: jax.Array) -> O.LinkFrames:
        """World-frame link states (position, rotation, origin and angular velocity) of states
        (qpos [..., nq], qvel [..., nv]), as MuJoCo's kinematics reports them (``physics/fk.py``:
        a lean tree walk, 4x cheaper than ``mjx.kinematics`` + ``com_vel`` on the 2-core CPU)."""
        return O.LinkFrames(*self._fk.frames(qpos, qvel))

    # ---- props -------------------------------------------------------------------------
    def props_of(self, data: mjx.Data, force: jax.Array | None = None) -> Props:
        """The props' state in ``data`` (``physics/props.py``) and their force channels."""
        p = self.num_props
        return Props(
            qpos=data.qpos[self._nq :].reshape(p, 7),
            qvel=data.qvel[self._nv :].reshape(p, 6),
            force=jnp.zeros((0,), jnp.float32) if force is None else force,
        )

    def place_props(self, data: mjx.Data, goal: Any) -> mjx.Data:
        """``data`` with the props where the task puts them (``Task.place``); moved props lose
        their solver warm start."""
        if not self.num_props:
            return data
        before = self.props_of(data)
        after = self.task.place(goal, before)
        moved = jnp.repeat(jnp.any(after.qvel != before.qvel, -1) | jnp.any(after.qpos != before.qpos, -1), 6)
        return data.replace(
            qpos=data.qpos.at[self._nq :].set(after.qpos.reshape(-1)),
            qvel=data.qvel.at[self._nv :].set(after.qvel.reshape(-1)),
            qacc_warmstart=data.qacc_warmstart.at[self._nv :].set(
                jnp.where(moved, 0.0, data.qacc_warmstart[self._nv :])
            ),
        )

    def character_qpos(self, qpos: jax.Array) -> jax.Array:
        """The character's part [..., 7 + n_dof] of a scene's ``qpos``."""
        return qpos[..., : self._nq]

    # ---- step --------------------------------------------------------------------------
    def pd_target(self, action: jax.Array, base: jax.Array | None = None) -> jax.Array:
        """PD targets of ``action`` [.., n_dof]: ``base`` (the task's ``pd_base``; None: the
        joint ranges' mid-points) + action_scale * action * half-range."""
        return (self._mid if base is None else base) + self.cfg.action_scale * action * self._half

    def power(self, data: mjx.Data, target: jax.Array) -> jax.Array:
        """The servo's mechanical power sum_j |tau_j qdot_j| (W) at ``data``, holding ``target``
        (the torque formula of ``sim.pd_torque``: the state after the step, not a substep mean)."""
        q, qd = data.qpos[7 : self._nq], data.qvel[6 : self._nv]
        tau = sim.pd_torque(self.character, q, qd, target, self.cfg.physics.servo_damping)
        return jnp.nan_to_num(jnp.sum(jnp.abs(tau * qd)), nan=0.0, posinf=0.0)

    def action_for_target(self, target: jax.Array, base: jax.Array | None = None) -> jax.Array:
        """The action whose PD target is ``target`` [.., n_dof] (inverse of ``pd_target``)."""
        return (target - (self._mid if base is None else base)) / (self.cfg.action_scale * self._half)

    def step(
        self, state: EnvState, action: jax.Array, reset: tuple[EnvState, jax.Array] | None = None
    ) -> tuple[EnvState, StepOut]:
        """One control step on the configured physics backend.

        ``reset``: the (state, observation) an environment that ends its episode here restarts
        from, e.g. one of a pool that ``reset`` made once per rollout (``Learner.rollout``); None
        draws a fresh one, which costs a full reset on every step for every environment (the
        ``where`` below keeps it only where an episode ended).
        """
        cfg = self.cfg
        action, bad_action = safe_action(action)
        target = self.pd_target(action, self.task.pd_base(state.goal))
        data, ground, force = self.physics.step_forces(state.data, target)
        # Contacts are those of the last substep's collision pass (one substep old); the link
        # frames are computed at the new state for the observations, in JAX for every backend.
        qvel_c = data.qvel[: self._nv]
        frame = self.frames_of(data.qpos[: self._nq], qvel_c)
        touching = fall_contacts(ground[: self._nb], self._bad_body, frame.pos[:, 2], cfg.fall_height)
        hist = jax.tree.map(lambda h, f: jnp.concatenate([h[1:], f[None]], 0), state.hist, frame)
        steps = state.steps + 1
        finite = jnp.all(jnp.isfinite(data.qpos)) & jnp.all(jnp.isfinite(data.qvel))
        # Only the character's speeds: a struck ball may spin faster than any joint may turn.
        unstable = bad_action | ~finite | jnp.any(jnp.abs(qvel_c) > cfg.max_qvel)
        fell = cfg.early_termination & jnp.any(touching) & (steps > cfg.contact_grace_steps)
        terminated = fell | unstable
        truncated = (steps >= cfg.episode_steps) & ~terminated
        clean = lambda x: jnp.where(unstable, 0.0, jnp.nan_to_num(x, posinf=0.0, neginf=0.0))
        hist = jax.tree.map(clean, hist)
        rng, k, k_task = jax.random.split(state.rng, 3)
        power = jnp.where(steps > 3, self.power(data, target), 0.0)  # the servo settles first (PHC's code)
        goal = self.task.sense(state.goal, self.props_of(data, force)) if self.num_props else state.goal
        task = self.task.step(goal, _last(state.hist), _last(hist), k_task, power)
        data = self.place_props(data, task.goal)
        task_reward = jnp.where(unstable, 0.0, task.rewards)
        terminated = terminated | (task.terminated & (steps > cfg.contact_grace_steps))
        truncated = (truncated | task.truncated) & ~terminated
        new_state = EnvState(data=data, hist=hist, steps=steps, rng=state.rng, goal=task.goal)
        final_obs = self.policy_obs(new_state)
        dobs = self.disc_obs(hist)
        reset_state, reset_obs = self.reset(k) if reset is None else reset
        done = terminated | truncated
        new_state = new_state.replace(rng=rng)
        out_state = jax.tree.map(lambda a, b: jnp.where(done, a, b), reset_state, new_state)
        obs = jnp.where(done, reset_obs, final_obs)
        return out_state, StepOut(
            obs=obs,
            final_obs=final_obs,
            disc_obs=dobs,
            terminated=terminated,
            truncated=truncated,
            unstable=unstable,
            task_reward=task_reward,
            info=task.info,
        )


ACTION_LIMIT = 1e3
"""|action| above this is absurd: a PD target a thousand half-ranges past the joint's middle (a
policy saturates the servo from |action| = 0.5 at the default ``action_scale``). MuJoCo C refuses
controls above 1e10 with a warning and steps on with them zeroed while MJX clips them, so such an
action, like a non-finite one, is treated as unstable physics on both backends."""


def safe_action(action: jax.Array, limit: float = ACTION_LIMIT) -> tuple[jax.Array, jax.Array]:
    """(``action`` with zeros in place of a non-finite or absurd one, whether it was): the
    environment is reset like one whose state went non-finite, and the physics never sees it."""
    bad = ~jnp.all(jnp.isfinite(action) & (jnp.abs(action) <= limit))
    return jnp.where(bad, jnp.zeros_like(action), action), bad


def joint_arrays(ch, allowed_contacts: Sequence[str]) -> tuple[jax.Array, ...]:
    """(mid-range, half-range, lower, upper limits [n_dof]; bodies whose ground contact is a fall
    [nb], i.e. all but ``allowed_contacts``) of a character, as float32 / bool arrays."""
    lo, hi = ch.joint_range[:, 0], ch.joint_range[:, 1]
    allowed = {ch.body_index(b) for b in allowed_contacts}
    f = lambda x: jnp.asarray(x, jnp.float32)
    return (
        f((lo + hi) / 2),
        f((hi - lo) / 2),
        f(lo),
        f(hi),
        jnp.asarray([b not in allowed for b in range(ch.num_bodies)]),
    )


def lowest_point(xpos: jax.Array, xmat: jax.Array, size: jax.Array, typ: jax.Array) -> jax.Array:
    """Height of the lowest point of geoms (spheres, capsules, boxes) with world positions
    ``xpos`` [G, 3], rotations ``xmat`` [G, 3, 3], sizes and types."""
    z, rot = xpos[:, 2], xmat
    axis_z = jnp.abs(rot[:, 2, :])  # |z component| of each geom axis
    low_sphere = z - size[:, 0]
    low_capsule = z - size[:, 0] - axis_z[:, 2] * size[:, 1]
    low_box = z - jnp.sum(axis_z * size, -1)
    low = jnp.where(typ == 2, low_sphere, jnp.where(typ == 3, low_capsule, low_box))
    return jnp.min(low)


def fall_contacts(ground: jax.Array, bad_body: jax.Array, body_z: jax.Array, fall_height: float) -> jax.Array:
    """[nb] bool: bodies whose ground contact is a fall (``EnvConfig.fall_height``): any but
    the allowed ones (``bad_body``), and with ``fall_height`` > 0 only while the body's origin
    height ``body_z`` is below it."""
    touching = ground & bad_body
    return touching & (body_z < fall_height) if fall_height > 0 else touching


def _last(hist: O.LinkFrames) -> O.LinkFrames:
    """The newest frame of a history."""
    return jax.tree.map(lambda x: x[-1], hist)
