"""The episode an exported policy is checked against: jaxmotion's own, on MuJoCo C.

``reference_episode`` rolls a run's policy out deterministically (mean actions) from one
reference-state initialisation on the MuJoCo C backend, and keeps what the standalone checker
(``check_policy.py``) needs to replay it without jaxmotion: the start window of F states, the
tracker's reference inputs per step, and per step the PD targets jaxmotion wrote, the states they
were computed from and the root height after the step.
"""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np

from jaxmotion.envs.humanoid import HumanoidEnv, safe_action
from jaxmotion.motion.motionlib import sample_times
from jaxmotion.physics import sim


@dataclasses.dataclass(frozen=True)
class Episode:
    """One deterministic episode (numpy, float32); T = the steps it lasted.

    Attributes:
      qpos, qvel: [F, nq], [F, nv] the start window, oldest first (the policy's first input).
      ref_qpos, ref_qvel: [T, nq], [T, nv] the tracker's reference inputs per step ([T, 0] else).
      state_qpos, state_qvel: [T, F, nq], [T, F, nv] the window each step's target was computed from.
      targets: [T, n_dof] the PD targets jaxmotion wrote.
      root_height: [T] root height after each step (m).
      ended: whether the episode was terminated (a fall, unstable physics, a tracker too far from
        its reference); one that hit its time limit or its clip's end just stops.
    """

    qpos: np.ndarray
    qvel: np.ndarray
    ref_qpos: np.ndarray
    ref_qvel: np.ndarray
    state_qpos: np.ndarray
    state_qvel: np.ndarray
    targets: np.ndarray
    root_height: np.ndarray
    ended: bool

    def arrays(self) -> dict[str, np.ndarray]:
        return {f.name: np.asarray(getattr(self, f.name)) for f in dataclasses.fields(self)}


def c_env(learner) -> HumanoidEnv:
    """The learner's scene on the MuJoCo C backend (one thread), on any device."""
    pc = dataclasses.replace(learner.cfg.env.physics, backend="mujoco", threads=1)
    env = learner.env
    return HumanoidEnv(learner.cfg.env, env.motion_libs, env.init_lib, physics=sim.physics(pc))


def reference_episode(learner, ts, steps: int, seed: int = 0) -> Episode:
    """The run's deterministic episode of at most ``steps`` control steps from the reset that
    ``seed`` draws, on MuJoCo C."""
    env = c_env(learner)
    f = env.cfg.policy_frames
    tracking = learner.cfg.env.task.name == "track"

    def start(key):
        # As ``HumanoidEnv.reset`` draws its start, keeping the state window it starts from.
        rng, k = jax.random.split(key)
        clip, t = sample_times(env.init_lib, k, 1)
        state, _ = env.reset_at(rng, clip[0], t[0])
        qpos_h, qvel_h, _ = env.start_window(jax.random.split(rng)[1], clip[0], t[0])
        return state, qpos_h.astype(jnp.float32), qvel_h.astype(jnp.float32)

    def step(carry, _):
        state, qpos_h, qvel_h, done = carry
        obs = env.policy_obs(state)
        mean, _, _ = learner.act(ts, obs[None], None)
        action, _ = safe_action(mean[0])
        target = env.pd_target(action, env.task.pd_base(state.goal))
        if tracking:
            ref = env.task.reference_coords(state.goal, env.dt)
        else:
            ref = (jnp.zeros((0,), jnp.float32), jnp.zeros((0,), jnp.float32))
        window = (qpos_h[-f:], qvel_h[-f:])
        new, out = env.step(state, mean[0], reset=(state, obs))
        q, v = new.data.qpos[: env._nq], new.data.qvel[: env._nv]
        qpos_h = jnp.concatenate([qpos_h[1:], q[None]])
        qvel_h = jnp.concatenate([qvel_h[1:], v[None]])
        # A terminal step's state is the reset one (here: the state before it); later steps repeat.
        record = (*ref, *window, target, q[2], done, out.terminated & ~done)
        return (new, qpos_h, qvel_h, done | out.terminated | out.truncated), record

    with jax.disable_jit(False):
        state, qpos_h, qvel_h = jax.jit(start)(jax.random.PRNGKey(seed))
        carry = (state, qpos_h, qvel_h, jnp.zeros((), bool))
        carry, rec = jax.jit(lambda c: jax.lax.scan(step, c, None, length=steps))(carry)
    rec = [np.asarray(x) for x in rec]
    n = int((~rec[6]).sum())
    return Episode(
        qpos=np.asarray(qpos_h[-f:]),
        qvel=np.asarray(qvel_h[-f:]),
        ref_qpos=rec[0][:n],
        ref_qvel=rec[1][:n],
        state_qpos=rec[2][:n],
        state_qvel=rec[3][:n],
        targets=rec[4][:n],
        root_height=rec[5][:n],
        ended=bool(rec[7].any()),
    )
