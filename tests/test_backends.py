"""The physics backends: MuJoCo C through a host callback and MJX agree, and the C path is
deterministic, runs without compilation under JAX_DISABLE_JIT=1 and handles a NaN state."""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from mujoco import mjx

from conftest import jit_enabled
from jaxmotion.motion import observations as O
from jaxmotion.envs.humanoid import EnvConfig, GroupConfig, HumanoidEnv
from jaxmotion.motion import MotionLib, make_test_clip
from jaxmotion.physics import backends, sim
from jaxmotion.physics.character import build_mjcf, character


def _physics(name: str, nthread: int | None = None):
    cfg = sim.PhysicsConfig()
    return backends.make_physics(
        name,
        sim.mj_model(cfg),
        build_mjcf(False),
        sim.mjx_model(sim.PhysicsConfig(backend="mjx")),
        cfg.substeps,
        nthread,
    )


def _states():
    """Two states: [0] in the air with a random pose and velocities, [1] standing on the floor."""
    rng = np.random.default_rng(1)
    m = sim.mj_model(sim.PhysicsConfig())
    lo, hi = character().joint_range.T + np.array([[0.1], [-0.1]])
    qpos = np.tile(m.qpos0, (2, 1))
    qpos[0, 2] = 2.0
    qpos[0, 7:] = np.clip(rng.uniform(-0.2, 0.2, m.nu), lo, hi)
    qpos[1, 2] = 0.89  # the zero-pose root height with the feet on the floor
    qvel = np.zeros((2, m.nv))
    qvel[0] = rng.uniform(-0.5, 0.5, m.nv)
    target = qpos[:, 7:] + np.array([[1.0], [0.0]]) * rng.uniform(-0.05, 0.05, (2, m.nu))
    d0 = mjx.make_data(sim.mjx_model(sim.PhysicsConfig(backend="mjx")))
    data = jax.vmap(lambda q, v: d0.replace(qpos=q, qvel=v))(
        jnp.asarray(qpos, jnp.float32), jnp.asarray(qvel, jnp.float32)
    )
    return data, jnp.asarray(target, jnp.float32)


@pytest.fixture(scope="module")
def trajectories():
    """60 control steps (2 s) of both states on both backends: qpos [T, 2, nq], contacts."""
    data0, target = _states()
    out = {}
    for name in ("mujoco", "mjx"):
        phys = _physics(name)
        with jit_enabled():
            step = jax.jit(jax.vmap(phys.step))
            d, qs, cs = data0, [], []
            for _ in range(60):
                d, c = step(d, target)
                qs.append(np.asarray(d.qpos))
                cs.append(np.asarray(c))
        out[name] = (np.stack(qs), np.stack(cs), d)
    return out


@pytest.mark.physics
def test_c_and_mjx_agree_in_the_air(trajectories):
    qc, qm = trajectories["mujoco"][0][:, 0], trajectories["mjx"][0][:, 0]
    # Ballistic flight with the servo near its targets: float64 C vs float32 MJX.
    np.testing.assert_allclose(qc[:5], qm[:5], atol=2e-3)
    # The root's parabola until just before the landing (at ~0.47 s), and no contact there.
    np.testing.assert_allclose(qc[:12, :3], qm[:12, :3], atol=5e-3)
    assert not trajectories["mujoco"][1][:12, 0].any() and not trajectories["mjx"][1][:12, 0].any()
    # Both land: some body touches the floor by the end.
    assert trajectories["mujoco"][1][-1, 0].any() and trajectories["mjx"][1][-1, 0].any()


@pytest.mark.physics
def test_c_and_mjx_agree_on_a_standing_hold(trajectories):
    for name in ("mujoco", "mjx"):
        q, c, _ = trajectories[name]
        assert q[:, 1, 2].min() > 0.85, name  # held for 2 s
        feet = [character().body_index(b) for b in ("right_foot", "left_foot")]
        assert c[-1, 1, feet].all() and c[-1, 1].sum() == 2, (name, c[-1, 1])
    qc, qm = trajectories["mujoco"][0][:, 1], trajectories["mjx"][0][:, 1]
    np.testing.assert_allclose(qc, qm, atol=5e-3)


@pytest.mark.physics
def test_env_observations_agree_for_the_same_state(trajectories):
    """Observations are one JAX function of qpos/qvel on either backend: the same state gives the
    same observation, and the two backends' standing holds give nearly the same one."""
    stand = MotionLib.from_clips([make_test_clip(10, 30.0)])
    envs = {
        name: HumanoidEnv(
            EnvConfig(groups=(GroupConfig(name="full"),), physics=sim.PhysicsConfig(backend=name)),
            motion_libs=(stand,),
            init_lib=stand,
        )
        for name in ("mujoco", "mjx")
    }
    assert {n: e.physics.name for n, e in envs.items()} == {"mujoco": "mujoco", "mjx": "mjx"}
    obs = {}
    with jit_enabled():
        for name, env in envs.items():
            f = jax.jit(
                jax.vmap(lambda q, v, env=env: O.policy_obs(jax.tree.map(lambda x: x[None], env.frames_of(q, v))))
            )
            obs[name] = {
                src: np.asarray(f(trajectories[src][2].qpos, trajectories[src][2].qvel)) for src in ("mujoco", "mjx")
            }
    for src in ("mujoco", "mjx"):
        np.testing.assert_array_equal(obs["mujoco"][src], obs["mjx"][src])
    np.testing.assert_allclose(obs["mujoco"]["mujoco"][1], obs["mujoco"]["mjx"][1], atol=5e-2)


def test_c_step_is_deterministic_whatever_the_threads():
    """The warm start is passed in, never left over in a thread's data: 1 or 2 threads, any
    order of calls, the same numbers."""
    data, target = _states()
    args = [np.asarray(x) for x in (data.qpos, data.qvel, data.qacc_warmstart)] + [np.asarray(target)]
    one = _physics("mujoco", nthread=1).host_step(*args)
    two = _physics("mujoco", nthread=2)
    two.host_step(*[a[::-1].copy() for a in args])  # leave other scratch data in the threads
    again = two.host_step(*args)
    for a, b in zip(one, again):
        np.testing.assert_array_equal(a, b)


def test_c_backend_steps_uncompiled():
    """Under JAX_DISABLE_JIT=1 the C backend steps physics without compiling anything: a standing
    hold for 2 s, and a non-finite state comes back non-finite (which the env resets; see
    ``test_env.test_nan_physics_resets_only_that_env``, on this backend by default on a CPU)."""
    phys = _physics("mujoco")
    data, target = _states()
    stand = jax.tree.map(lambda x: x[1:], data)
    hold = target[1:]
    for _ in range(60):
        stand, contact = phys.step(stand, hold)
    assert float(stand.qpos[0, 2]) > 0.85 and bool(contact[0].sum() == 2)
    bad = stand.replace(qvel=stand.qvel.at[0, 8].set(jnp.nan))
    out, _ = phys.step(bad, hold)
    assert not bool(jnp.isfinite(out.qpos).all() & jnp.isfinite(out.qvel).all())


def test_default_backend_on_this_machine():
    stand = MotionLib.from_clips([make_test_clip(10, 30.0)])
    env = HumanoidEnv(EnvConfig(groups=(GroupConfig(name="full"),)), motion_libs=(stand,), init_lib=stand)
    assert env.physics.name == ("mujoco" if jax.default_backend() == "cpu" else "mjx")


def test_backend_names():
    assert backends.resolve_backend("mjx") == "mjx"
    assert backends.resolve_backend("auto") == ("mujoco" if jax.default_backend() == "cpu" else "mjx")
    with pytest.raises(ValueError, match="backend"):
        backends.resolve_backend("bullet")


def _saturated_substep(servo_damping: str) -> dict[str, np.ndarray]:
    """qvel after one 120-Hz substep from the in-air state of ``_states`` with every PD target
    0.8 rad away, so that every actuator sits at its torque limit, on both backends."""
    data0, _ = _states()
    data0 = jax.tree.map(lambda x: x[:1], data0)
    target = data0.qpos[:, 7:] + 0.8
    out = {}
    for name in ("mujoco", "mjx"):
        cfg = sim.PhysicsConfig(control_hz=120.0, servo_damping=servo_damping, backend=name)
        phys = backends.make_physics(name, sim.mj_model(cfg), build_mjcf(False), sim.mjx_model(cfg), 1)
        with jit_enabled():
            d, _ = jax.jit(jax.vmap(phys.step))(data0, target)
        out[name] = np.asarray(d.qvel[0, 6:])
    return out


@pytest.mark.physics
def test_c_and_mjx_agree_on_a_saturated_substep():
    """With every actuator at its torque limit, MuJoCo C leaves the clamped actuators out of the
    implicit damping; MJX does the same (``backends._clamped_servo``), so the engines agree after
    one saturated substep, with the damping in the actuator (the default) or on the joint. The
    saturated motors then push with their full torque (tens of rad/s in one substep), where the
    joint's own damping holds them to a few rad/s."""
    act = _saturated_substep("actuator")
    joint = _saturated_substep("joint")
    for out in (act, joint):
        np.testing.assert_allclose(out["mujoco"], out["mjx"], atol=0.01 * np.abs(out["mujoco"]).max())
    assert np.abs(act["mujoco"]).max() > 20.0
    assert np.abs(joint["mujoco"]).max() < 0.5 * np.abs(act["mujoco"]).max()


def test_servo_damping_moves_kd_to_the_joints_and_is_checked():
    m_act = sim.mj_model(sim.PhysicsConfig())
    m_joint = sim.mj_model(sim.PhysicsConfig(servo_damping="joint"))
    dof = m_act.jnt_dofadr[m_act.actuator_trnid[:, 0]]
    np.testing.assert_array_equal(m_joint.dof_damping[dof], character().kd)
    assert not m_joint.actuator_biasprm[:, 2].any() and not m_act.dof_damping.any()
    q, qd, t = (jnp.asarray(np.full(m_act.nu, v), jnp.float32) for v in (0.0, 2.0, 1.0))
    ch = character()  # the formula: clip(kp (t - q)) - kd qd with the damping on the joint
    np.testing.assert_allclose(
        sim.pd_torque(ch, q, qd, t, "joint"),
        np.clip(ch.kp * 1.0, -ch.max_torque, ch.max_torque) - ch.kd * 2.0,
        rtol=1e-6,
    )
    with pytest.raises(ValueError, match="servo_damping"):
        sim.PhysicsConfig(servo_damping="spring")


@pytest.mark.physics
@pytest.mark.parametrize("name", ["mujoco", "mjx"])
def test_nan_or_absurd_action_resets_only_its_env(name, tmp_path, monkeypatch):
    """A non-finite or absurd action is unstable physics on both backends: its environment is
    reset, the others step as if it were not there, nothing non-finite comes out, MuJoCo is
    never asked to step it (no warning) and nothing is written to the working directory."""
    monkeypatch.chdir(tmp_path)
    stand = MotionLib.from_clips([make_test_clip(10, 30.0)])
    env = HumanoidEnv(
        EnvConfig(groups=(GroupConfig(name="full"),), physics=sim.PhysicsConfig(backend=name)),
        motion_libs=(stand,),
        init_lib=stand,
    )
    backends.WARNINGS.take()
    hold = np.asarray(env.action_for_target(jnp.zeros(env.action_size)))
    actions = np.tile(hold, (4, 1))
    actions[1, 3] = np.nan
    actions[2, 0] = 1e30
    actions[3, 5] = -np.inf
    with jit_enabled():
        reset = jax.jit(jax.vmap(env.reset))
        step = jax.jit(jax.vmap(env.step))
        state, _ = reset(jax.random.split(jax.random.PRNGKey(0), 4))
        state, _ = step(state, jnp.tile(hold, (4, 1)))  # one step in, so a reset shows as steps == 0
        new, out = step(state, jnp.asarray(actions))
        ref, _ = step(state, jnp.tile(hold, (4, 1)))
    np.testing.assert_array_equal(np.asarray(out.unstable), [False, True, True, True])
    assert bool(out.terminated[1:].all())
    np.testing.assert_array_equal(np.asarray(new.steps), [2, 0, 0, 0])
    assert all(
        bool(jnp.isfinite(x).all()) for x in jax.tree.leaves((new, out)) if jnp.issubdtype(x.dtype, jnp.floating)
    )
    np.testing.assert_array_equal(np.asarray(new.data.qpos[0]), np.asarray(ref.data.qpos[0]))
    assert backends.WARNINGS.take() == {}
    assert list(tmp_path.iterdir()) == []


def test_mujoco_warnings_are_counted_not_written_to_the_working_directory(tmp_path, monkeypatch):
    """MuJoCo C warns about a NaN control: the warning is counted per message, and no
    ``MUJOCO_LOG.TXT`` appears where the user runs the command."""
    monkeypatch.chdir(tmp_path)
    phys = _physics("mujoco", nthread=2)
    data, target = _states()
    backends.WARNINGS.take()
    args = [np.asarray(x) for x in (data.qpos, data.qvel, data.qacc_warmstart)]
    phys.host_step(*args, np.full(np.shape(target), np.nan, np.float32))
    counts = backends.WARNINGS.take()
    assert sum(counts.values()) == 2 and all("CTRL" in k for k in counts)
    assert backends.WARNINGS.take() == {}
    assert list(tmp_path.iterdir()) == []
