"""Two players in one scene: the boxing ring or the fencing piste, stepped as one physics model.

``BoutEnv(cfg)`` has the interface of ``HumanoidEnv`` with a leading player axis of 2 on
everything per player: ``reset(rng) -> (state, obs [2, obs_dim])`` and ``step(state, action
[2, A]) -> (state, StepOut)`` whose ``obs``, ``final_obs``, ``terminated``, ``truncated``,
``unstable``, ``task_reward`` ([2, R]) and ``info`` values ([2]) are per player. The learner
treats every player as a sample of its own (``Learner.players``): one shared policy acts for
both, latest against latest (self-play), and each player's transitions train it.

* **Physics**: ``physics/arena.py``'s two-character model on the configured backend (MJX or
  MuJoCo C in the loop), with the scoring force channels read on every substep.
* **Rules**: the task (``tasks/bout.py``: ``boxing`` or ``fencing``) owns the start placement,
  the rules' state, the task observation, rewards, penalties and results.
* **Episode ends** are per player: a player whose own penalty ends the bout (a fall, stuck
  timers, leaving the piste) is *terminated*; the other player is *truncated* (its value is
  bootstrapped: the bout was stopped for it, not lost). A fencing result ends the bout as
  terminal for both, after paying the result. The round's time limit truncates both. Both
  players restart together.
* **Start**: each player from a random frame of a random init clip (reference-state
  initialisation), moved and turned to the task's start placement.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct
from mujoco import mjx

from jaxmotion.config.checks import validate
from jaxmotion.config.errors import ConfigError
from jaxmotion.motion import observations as O
from jaxmotion.envs.humanoid import StepOut, joint_arrays, lowest_point, safe_action
from jaxmotion.motion import rotations as R
from jaxmotion.motion.motionlib import load_motionlib, qpos_qvel, sample, sample_times
from jaxmotion.physics import arena as A
from jaxmotion.physics import backends, sim
from jaxmotion.physics.character import character
from jaxmotion.physics.fk import LinkFK
from jaxmotion.tasks import make_task

PLAYERS = 2


@struct.dataclass
class BoutState:
    """One bout: the shared physics state, both players' link frames [2, nb, ...], the rules."""

    data: mjx.Data
    frame: O.LinkFrames
    steps: jax.Array
    rng: jax.Array
    goal: Any = None


class BoutEnv:
    """Pure-functional two-player environment (see the module docstring)."""

    players = PLAYERS

    def __init__(self, cfg, init_lib=None, physics=None):
        self.cfg = validate(cfg, "env")  # EnvConfig.checks: groups, init clips, arena, two-player task
        ac = cfg.arena
        sport = A.SPORTS[ac.sport]
        self.character = ch = character(sport.sword_shield)
        self.layout = A.layout(ac)
        pc = cfg.physics
        m = sim.apply_settings(A.arena_model(ac).__copy__(), pc)
        self.mj = m
        self.model = mjx.put_model(m, impl=sim._impl(pc))
        self.channels = A.channels(ac, m)
        self.physics = (
            physics
            if physics is not None
            else backends.make_physics(
                pc.backend, m, A.arena_mjcf(ac), self.model, pc.substeps, pc.threads or None, self.channels
            )
        )
        self.groups, self.group_idx, self.motion_libs = [], [], ()
        self.init_lib = (
            init_lib if init_lib is not None else load_motionlib(cfg.init_motions, ch, drop_props=cfg.drop_props)
        )
        self._mid, self._half, self._lo, self._hi, self._bad_body = joint_arrays(ch, cfg.allowed_contacts)
        self._data0 = mjx.make_data(self.model)
        self._fk = LinkFK(m)
        # Per player: its body geoms (spheres, capsules, boxes; for the start's lift above the floor).
        lay = self.layout
        self._geoms = []
        for k in range(PLAYERS):
            b0, b1 = lay.bodies(k).start, lay.bodies(k).stop
            geoms = [g for g in range(m.ngeom) if b0 <= m.geom_bodyid[g] < b1 and m.geom_type[g] in (2, 3, 6)]
            self._geoms.append(
                (
                    np.asarray(geoms),
                    jnp.asarray(m.geom_size[geoms], jnp.float32),
                    jnp.asarray(m.geom_type[geoms], jnp.int32),
                )
            )
        self.task = make_task(cfg.task, self)
        if not getattr(self.task, "two_player", False):
            raise ConfigError(f"env.task.name={cfg.task.name}: is not a two-player task (boxing, fencing)")

    # ---- sizes -------------------------------------------------------------------------
    @property
    def action_size(self) -> int:
        return self.character.num_dof

    @property
    def body_obs_size(self) -> int:
        return self.character.num_bodies * 15

    @property
    def obs_size(self) -> int:
        return self.body_obs_size + self.task.goal_size

    def disc_obs_sizes(self) -> tuple[int, ...]:
        return ()

    def ref_disc_obs(self, rng: jax.Array, n: int) -> tuple[jax.Array, ...]:
        return ()

    @property
    def dt(self) -> float:
        return self.cfg.physics.control_dt

    # ---- kinematics --------------------------------------------------------------------
    def frames_of(self, qpos: jax.Array, qvel: jax.Array) -> O.LinkFrames:
        """Both players' link frames [..., 2, nb, ...] of the scene's qpos/qvel."""
        f = O.LinkFrames(*self._fk.frames(qpos, qvel))
        nb = self.layout.nb
        return jax.tree.map(lambda x: x.reshape(x.shape[:-2] + (PLAYERS, nb, x.shape[-1])), f)

    def poses_of(self, qpos: jax.Array) -> tuple[jax.Array, jax.Array]:
        """Both players' link positions [..., 2, nb, 3] and orientations [..., 2, nb, 4]."""
        pos, quat = self._fk(qpos)
        nb = self.layout.nb
        return (pos.reshape(pos.shape[:-2] + (PLAYERS, nb, 3)), quat.reshape(quat.shape[:-2] + (PLAYERS, nb, 4)))

    def player_qpos(self, qpos: jax.Array) -> jax.Array:
        """[..., 2, nq1] from the scene's [..., 2 * nq1]."""
        return qpos.reshape(qpos.shape[:-1] + (PLAYERS, self.layout.nq))

    def player_qvel(self, qvel: jax.Array) -> jax.Array:
        return qvel.reshape(qvel.shape[:-1] + (PLAYERS, self.layout.nv))

    # ---- reset -------------------------------------------------------------------------
    def reset(self, rng: jax.Array, clip_weight: jax.Array | None = None) -> tuple[BoutState, jax.Array]:
        """Both players from random clip frames, placed as the task's start rule says."""
        rng, k_clip, k_place, k_goal = jax.random.split(rng, 4)
        lib = self.init_lib if clip_weight is None else self.init_lib.replace(clip_weight=clip_weight)
        clip, t = sample_times(lib, k_clip, PLAYERS)
        qpos, qvel = qpos_qvel(sample(self.init_lib, clip, t))  # [2, nq1], [2, nv1]
        qpos = qpos.at[:, 7:].set(jnp.clip(qpos[:, 7:], self._lo, self._hi))
        xy, yaw = self.task.start(k_place)
        qpos, qvel = jax.vmap(place)(qpos, qvel, xy, yaw)
        data = self._data0.replace(qpos=qpos.reshape(-1))
        lift = jnp.maximum(-self.lowest_points(data.qpos), 0.0)
        qpos = qpos.at[:, 2].add(lift)
        data = data.replace(qpos=qpos.reshape(-1), qvel=qvel.reshape(-1))
        frame = self.frames_of(data.qpos, data.qvel)
        goal = self.task.init(k_goal, frame)
        state = BoutState(data=data, frame=frame, steps=jnp.zeros((), jnp.int32), rng=rng, goal=goal)
        return state, self.policy_obs(state)

    def lowest_points(self, qpos: jax.Array) -> jax.Array:
        """[2] height of each player's lowest geom point at the scene's ``qpos``."""
        return jnp.stack([lowest_point(*self._fk.geom_frames(qpos, g), size, typ) for g, size, typ in self._geoms])

    # ---- observations ------------------------------------------------------------------
    def policy_obs(self, state: BoutState) -> jax.Array:
        """[2, obs_dim]: each player's own body in its heading frame, then the task features."""
        body = jax.vmap(lambda f: O.policy_obs(jax.tree.map(lambda x: x[None], f)))(state.frame)
        goal = jnp.stack([self.task.observe(state.goal, state.frame, k) for k in range(PLAYERS)])
        return jnp.concatenate([body, goal], -1)

    # ---- step --------------------------------------------------------------------------
    def pd_target(self, action: jax.Array) -> jax.Array:
        return (self._mid + self.cfg.action_scale * action * self._half).reshape(-1)

    def step(
        self, state: BoutState, action: jax.Array, reset: tuple[BoutState, jax.Array] | None = None
    ) -> tuple[BoutState, StepOut]:
        """One control step of both players (``action`` [2, A]); see the module docstring."""
        cfg = self.cfg
        action, bad_action = safe_action(action)
        data, ground, forces = self.physics.step_forces(state.data, self.pd_target(action))
        ground = ground.reshape(PLAYERS, self.layout.nb)
        steps = state.steps + 1
        finite = jnp.all(jnp.isfinite(data.qpos)) & jnp.all(jnp.isfinite(data.qvel))
        unstable = bad_action | ~finite | jnp.any(jnp.abs(data.qvel) > cfg.max_qvel)
        clean = lambda x: jnp.where(unstable, 0.0, jnp.nan_to_num(x, posinf=0.0, neginf=0.0))
        frame = jax.tree.map(clean, self.frames_of(data.qpos, data.qvel))
        fell = jnp.any(ground & self._bad_body, -1) & (steps > cfg.contact_grace_steps) & cfg.early_termination
        rng, k_reset, k_task = jax.random.split(state.rng, 3)
        qvel0 = self.player_qvel(state.data.qvel)
        task = self.task.step(
            state.goal,
            state.frame,
            frame,
            clean(forces),
            fell,
            qvel0,
            self.player_qvel(clean(data.qvel)),
            steps,
            k_task,
        )
        rewards = jnp.where(unstable, 0.0, task.rewards)
        terminated = task.terminated | unstable
        time_up = (steps >= cfg.episode_steps) | jnp.any(task.truncated)
        done = jnp.any(terminated) | time_up
        truncated = done & ~terminated
        unstable = jnp.broadcast_to(unstable, (PLAYERS,))
        new_state = BoutState(data=data, frame=frame, steps=steps, rng=rng, goal=task.goal)
        final_obs = self.policy_obs(new_state)
        reset_state, reset_obs = self.reset(k_reset) if reset is None else reset
        out_state = jax.tree.map(lambda a, b: jnp.where(done, a, b), reset_state, new_state)
        obs = jnp.where(done, reset_obs, final_obs)
        return out_state, StepOut(
            obs=obs,
            final_obs=final_obs,
            disc_obs=(),
            terminated=terminated,
            truncated=truncated,
            unstable=unstable,
            task_reward=rewards,
            info=task.info,
        )


def place(qpos: jax.Array, qvel: jax.Array, xy: jax.Array, yaw: jax.Array) -> tuple[jax.Array, jax.Array]:
    """One character's (qpos, qvel) turned about the vertical to heading ``yaw`` and moved to
    ``xy``; the world-frame root velocity turns with it (the free joint's angular velocity is
    in the body frame and stays)."""
    turn = R.quat_mul(R._yaw_quat(yaw), R.heading_inv(qpos[3:7]))
    quat = R.quat_normalize(R.quat_mul(turn, qpos[3:7]))
    qpos = jnp.concatenate([xy, qpos[2:3], quat, qpos[7:]])
    qvel = qvel.at[:3].set(R.quat_rotate(turn, qvel[:3]))
    return qpos, qvel


def make_env(cfg, **kw):
    """The scene ``cfg`` describes: ``HumanoidEnv`` for one player, ``BoutEnv`` for two."""
    if cfg.players == 1:
        from jaxmotion.envs.humanoid import HumanoidEnv

        return HumanoidEnv(cfg, **kw)
    if cfg.players == PLAYERS:
        return BoutEnv(cfg, **kw)
    raise ConfigError(f"env.players={cfg.players}: must be 1 or 2")


def env_bytes(env, horizon: int) -> int:
    """Bytes one environment takes in a training iteration, at least: its physics state (the
    scene's data template; else a reset's state, traced without running) and observation twice
    (the carried ones and the rollout's fresh resets), and ``horizon`` steps of the transitions'
    observations, actions and discriminator views (float32)."""
    data = getattr(env, "_data0", None)
    state = data if data is not None else jax.eval_shape(env.reset, jax.random.PRNGKey(0))
    players = getattr(env, "players", 1)
    obs = env.obs_size * players
    step = 2 * obs + 3 * env.action_size * players + sum(env.disc_obs_sizes())
    return 2 * (sum(x.size * x.dtype.itemsize for x in jax.tree.leaves(state)) + 4 * obs) + 4 * horizon * step
