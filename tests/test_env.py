"""The humanoid environment: standing, falls, determinism, NaN resets, sim/reference views."""

from __future__ import annotations


import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from conftest import jit_enabled
from jaxmotion.motion import observations as O
from jaxmotion.envs.humanoid import EnvConfig, GroupConfig, HumanoidEnv, fall_contacts
from jaxmotion.motion import MotionLib, make_test_clip, qpos_qvel, sample
from jaxmotion.physics import backends, sim
from jaxmotion.physics.character import build_mjcf

B = 3


def _moving_clip():
    """A clip with every joint moving smoothly, a turning and translating root."""
    t = np.arange(40)[:, None] / 30.0
    dof = 0.3 * np.sin(2.0 * t + np.arange(28)[None] * 0.7)
    return make_test_clip(40, 30.0, root_vel=(0.5, 0.2, 0.0), root_height=1.0, yaw_rate=0.8, dof_pos=dof, name="moving")


@pytest.fixture(scope="module")
def env():
    stand = make_test_clip(30, 30.0, root_vel=(0.0, 0.0, 0.0), root_height=0.87, name="stand")
    lib = MotionLib.from_clips([stand])
    moving = MotionLib.from_clips([_moving_clip()])
    cfg = EnvConfig(groups=(GroupConfig(name="upper"), GroupConfig(name="lower")), episode_steps=70)
    return HumanoidEnv(cfg, motion_libs=(moving, moving), init_lib=lib)


@pytest.fixture(scope="module")
def fns(env):
    with jit_enabled():
        reset = jax.jit(jax.vmap(env.reset))
        step = jax.jit(jax.vmap(env.step))
        frames = jax.jit(env.frames_of)
    return reset, step, frames


def _zero_gain_env(env, cfg=None):
    """The same env (or config ``cfg``) on a physics backend whose servo has no gains."""
    m = sim.mj_model(env.cfg.physics)
    m.actuator_gainprm[:, 0] = 0
    m.actuator_biasprm[:, 1:3] = 0
    phys = backends.make_physics(
        env.cfg.physics.backend, m, build_mjcf(False), sim.mjx.put_model(m), env.cfg.physics.substeps
    )
    return HumanoidEnv(cfg or env.cfg, motion_libs=env.motion_libs, init_lib=env.init_lib, physics=phys)


def _run(fns, env, key, actions):
    reset, step, _ = fns
    with jit_enabled():
        state, obs = reset(jax.random.split(key, B))
        outs, zs = [], []
        for a in actions:
            state, out = step(state, a)
            outs.append(out)
            zs.append(state.data.qpos[:, 2])
    return state, obs, outs, jnp.stack(zs)


def test_sizes(env):
    assert env.obs_size == 4 * 15 * 15
    assert env.disc_obs_sizes() == (5 * 8 * 9, 5 * 7 * 9)
    assert env.cfg.physics.substeps == 4


def test_standing_holds_for_2s_and_zero_gains_fall(env, fns):
    hold = jnp.broadcast_to(env.action_for_target(jnp.zeros(28)), (60, B, 28))
    _, _, outs, z = _run(fns, env, jax.random.PRNGKey(0), hold)
    assert not any(bool(o.terminated.any()) for o in outs)
    assert float(z.min()) > 0.8, "the PD servo should hold the standing pose for 2 s"
    zero = _zero_gain_env(env)
    with jit_enabled():
        zfns = (jax.jit(jax.vmap(zero.reset)), jax.jit(jax.vmap(zero.step)), None)
    _, _, outs, z = _run(zfns, zero, jax.random.PRNGKey(0), hold)
    fell = jnp.stack([o.terminated for o in outs])
    assert bool(fell.any(0).all()), "without gains every character should fall and terminate"
    assert not bool(jnp.stack([o.unstable for o in outs]).any())


def test_fall_rule_with_a_height():
    """By hand: a hand (body 1) and a foot (body 2, allowed) on the ground, the hand's origin at
    0.10 m: a fall by the default rule and under 0.15 m, not under 0.05 m (the authors' rule)."""
    ground = jnp.array([False, True, True])
    bad = jnp.array([True, True, False])
    z = jnp.array([0.9, 0.10, 0.05])
    assert fall_contacts(ground, bad, z, 0.0).tolist() == [False, True, False]
    assert fall_contacts(ground, bad, z, 0.15).tolist() == [False, True, False]
    assert fall_contacts(ground, bad, z, 0.05).tolist() == [False, False, False]


def test_a_collapse_touching_with_links_up_is_no_fall_under_a_low_fall_height(env):
    """No servo: the character collapses and its knees, hands or pelvis touch the floor, but body
    origins (joints) stay above 1 mm, so with ``fall_height`` 1 mm the episode goes on."""
    import dataclasses

    zero = _zero_gain_env(env, dataclasses.replace(env.cfg, fall_height=1e-3))
    with jit_enabled():
        zfns = (jax.jit(jax.vmap(zero.reset)), jax.jit(jax.vmap(zero.step)), None)
    hold = jnp.broadcast_to(env.action_for_target(jnp.zeros(28)), (60, B, 28))
    _, _, outs, z = _run(zfns, zero, jax.random.PRNGKey(0), hold)
    assert float(z[-1].max()) < 0.4, "the character should have collapsed"
    assert not bool(jnp.stack([o.terminated for o in outs]).any())


def test_time_limit_truncates_and_resets(env, fns):
    hold = jnp.broadcast_to(env.action_for_target(jnp.zeros(28)), (71, B, 28))
    state, _, outs, _ = _run(fns, env, jax.random.PRNGKey(3), hold)
    trunc = jnp.stack([o.truncated for o in outs])
    assert bool(trunc[69].all()) and not bool(trunc[:69].any())
    assert int(state.steps[0]) == 1  # reset at step 70, then one more step


def test_an_ended_episode_restarts_from_the_given_reset(env, fns):
    """``step(..., reset=pool)``: an environment whose episode ends takes its pool entry (state and
    observation), the others go on; without a pool it draws a fresh reset of its own."""
    reset, _, _ = fns
    with jit_enabled():
        step = jax.jit(jax.vmap(env.step))
        state, _ = reset(jax.random.split(jax.random.PRNGKey(5), B))
        pool = reset(jax.random.split(jax.random.PRNGKey(6), B))
        state = state.replace(steps=state.steps.at[0].set(env.cfg.episode_steps - 1))
        hold = jnp.broadcast_to(env.action_for_target(jnp.zeros(28)), (B, 28))
        new, out = step(state, hold, pool)
        fresh, fresh_out = step(state, hold)
    assert bool(out.truncated[0]) and not bool((out.truncated | out.terminated)[1:].any())
    for a, b in zip(jax.tree.leaves(new), jax.tree.leaves(pool[0])):
        np.testing.assert_array_equal(a[0], b[0])
    np.testing.assert_array_equal(out.obs[0], pool[1][0])
    for a, b in zip(jax.tree.leaves(new), jax.tree.leaves(fresh)):
        np.testing.assert_array_equal(a[1:], b[1:])
    assert not np.array_equal(fresh.rng[0], pool[0].rng[0])  # a reset of its own
    np.testing.assert_array_equal(out.final_obs, fresh_out.final_obs)


def test_reset_step_deterministic_finite(env, fns):
    acts = 0.5 * jax.random.normal(jax.random.PRNGKey(1), (20, B, 28))
    s1, o1, out1, _ = _run(fns, env, jax.random.PRNGKey(2), acts)
    s2, o2, out2, _ = _run(fns, env, jax.random.PRNGKey(2), acts)
    np.testing.assert_array_equal(o1, o2)
    for a, b in zip(jax.tree.leaves(s1), jax.tree.leaves(s2)):
        np.testing.assert_array_equal(a, b)
    assert o1.shape == (B, env.obs_size)
    for o in out1:
        assert o.obs.shape == (B, env.obs_size) and o.final_obs.shape == (B, env.obs_size)
        assert [d.shape for d in o.disc_obs] == [(B, n) for n in env.disc_obs_sizes()]
        assert all(bool(jnp.isfinite(x).all()) for x in jax.tree.leaves(o))
    assert all(bool(jnp.isfinite(x).all()) for x in jax.tree.leaves(s1))


def test_nan_physics_resets_only_that_env(env, fns):
    reset, step, _ = fns
    with jit_enabled():
        state, _ = reset(jax.random.split(jax.random.PRNGKey(4), B))
        bad = state.replace(data=state.data.replace(qvel=state.data.qvel.at[1, 10].set(jnp.nan)))
        hold = jnp.broadcast_to(env.action_for_target(jnp.zeros(28)), (B, 28))
        new, out = step(bad, hold)
        ref, ref_out = step(state, hold)
    assert bool(out.unstable[1]) and bool(out.terminated[1]) and not bool(out.unstable[jnp.array([0, 2])].any())
    assert all(bool(jnp.isfinite(x).all()) for x in jax.tree.leaves((new, out)))
    assert int(new.steps[1]) == 0  # was reset
    np.testing.assert_array_equal(new.data.qpos[0], ref.data.qpos[0])  # others untouched


def test_link_velocities_match_mujoco(env, fns):
    _, _, kin = fns
    m = sim.mj_model(env.cfg.physics)
    d = mujoco.MjData(m)
    rng = np.random.default_rng(0)
    d.qpos[:3] = [0.3, -0.2, 1.1]
    d.qpos[3:7] = np.array([0.9, 0.1, -0.2, 0.3]) / np.linalg.norm([0.9, 0.1, -0.2, 0.3])
    d.qpos[7:] = rng.uniform(-0.3, 0.3, 28)
    d.qvel[:] = rng.uniform(-1, 1, 34)
    mujoco.mj_forward(m, d)
    with jit_enabled():
        lf = kin(jnp.asarray(d.qpos, jnp.float32), jnp.asarray(d.qvel, jnp.float32))
    res = np.zeros(6)
    for b in range(15):
        mujoco.mj_objectVelocity(m, d, mujoco.mjtObj.mjOBJ_XBODY, b + 1, res, 0)
        np.testing.assert_allclose(lf.ang_vel[b], res[:3], atol=1e-4)
        np.testing.assert_allclose(lf.lin_vel[b], res[3:], atol=1e-4)
    np.testing.assert_allclose(lf.pos, d.xpos[1:], atol=1e-5)
    q = np.asarray(lf.quat)
    np.testing.assert_allclose(q * np.sign(q[:, :1] * d.xquat[1:, :1]), d.xquat[1:], atol=1e-5)


def test_reference_and_simulation_discriminator_views_agree(env, fns):
    """Set the simulator to reference states frame by frame: both sides see the same window."""
    _, _, kin = fns
    lib = env.motion_libs[0]
    times = jnp.asarray(0.4 + env.dt * np.arange(5), jnp.float32)
    ms = sample(lib, jnp.zeros(5, jnp.int32), times)
    frames = []
    with jit_enabled():
        for k in range(5):
            qpos, qvel = qpos_qvel(jax.tree.map(lambda x, k=k: x[k], ms))
            frames.append(kin(qpos, qvel))
    hist = jax.tree.map(lambda *x: jnp.stack(x), *frames)
    sim_views = env.disc_obs(hist)
    for g, (links, anchor) in enumerate(env.group_idx):
        ref_view = O.disc_obs(ms.body_pos, ms.body_quat, links, int(anchor))
        np.testing.assert_allclose(sim_views[g], ref_view, atol=2e-4)
    # The policy sees the same link positions and orientations, too.
    ref_hist = O.LinkFrames(ms.body_pos, ms.body_quat, hist.lin_vel, hist.ang_vel)
    np.testing.assert_allclose(O.policy_obs(hist), O.policy_obs(ref_hist), atol=2e-4)


def test_servo_power_matches_mujoco_actuator_forces(env):
    """``env.power`` (the tracker's energy penalty) is sum |tau qdot| with MuJoCo's own actuator
    forces (gain * ctrl + bias, clipped to the torque limit) at the same state and targets."""
    m = sim.mj_model(env.cfg.physics)
    d = mujoco.MjData(m)
    rng = np.random.default_rng(0)
    d.qpos[2] = 1.0
    d.qpos[7:] = rng.uniform(-0.3, 0.3, m.nu)
    d.qvel[6:] = rng.uniform(-3.0, 3.0, m.nu)
    target = rng.uniform(-1.0, 1.0, m.nu)
    d.ctrl[:] = target
    mujoco.mj_forward(m, d)
    want = np.sum(np.abs(d.actuator_force * d.qvel[6:]))
    data = env._data0.replace(qpos=jnp.asarray(d.qpos, jnp.float32), qvel=jnp.asarray(d.qvel, jnp.float32))
    np.testing.assert_allclose(float(env.power(data, jnp.asarray(target, jnp.float32))), want, rtol=1e-4)


@pytest.mark.parametrize("within", [True, False])
def test_reference_windows_stay_within_the_joint_ranges(within):
    """A clip held in a pose 0.3 rad beyond every joint's upper limit: with ``ref_within_limits``
    the discriminators' reference windows are the views of the pose clamped to the ranges (what
    the simulated character can show), without it those of the raw pose."""
    ch_env = HumanoidEnv(
        EnvConfig(groups=(GroupConfig(name="upper"), GroupConfig(name="lower")), ref_within_limits=within),
        motion_libs=(MotionLib.from_clips([make_test_clip(30, 30.0, root_vel=(0, 0, 0))]),) * 2,
    )
    hi = np.asarray(ch_env._hi)
    beyond = make_test_clip(30, 30.0, root_vel=(0.0, 0.0, 0.0), dof_pos=hi + 0.3, name="beyond")
    lib = MotionLib.from_clips([beyond])
    env = HumanoidEnv(ch_env.cfg, motion_libs=(lib, lib))
    views = env.ref_disc_obs(jax.random.PRNGKey(0), 3)
    qpos = np.asarray(qpos_qvel(sample(lib, jnp.zeros(1, jnp.int32), jnp.full(1, 0.5)))[0][0])
    expect_q = qpos.copy()
    if within:
        expect_q[7:] = hi
    pos, quat = env.poses_of(jnp.asarray(expect_q))
    frames = env.cfg.groups[0].frames
    for g, (links, anchor) in enumerate(env.group_idx):
        one = O.disc_obs(
            jnp.broadcast_to(pos, (frames,) + pos.shape),
            jnp.broadcast_to(quat, (frames,) + quat.shape),
            links,
            int(anchor),
        )
        np.testing.assert_allclose(views[g], np.broadcast_to(one, views[g].shape), atol=1e-4)


def test_lowest_point_matches_mujoco(env):
    """The start's lift above the floor uses the lowest geom point of the lean kinematics; MuJoCo C
    poses the same geoms for the reference."""
    from jaxmotion.motion.level import _lowest_points

    m = sim.mj_model(env.cfg.physics)
    d = mujoco.MjData(m)
    geoms = [g for g in range(m.ngeom) if m.geom_bodyid[g] != 0 and m.geom_type[g] in (2, 3, 6)]
    rng = np.random.default_rng(0)
    for _ in range(3):
        q = m.qpos0.copy()
        q[2] = 0.3
        q[3:7] = rng.normal(size=4)
        q[3:7] /= np.linalg.norm(q[3:7])
        q[7:] = rng.uniform(-1.0, 1.0, m.nq - 7)
        d.qpos[:] = q
        mujoco.mj_kinematics(m, d)
        want = _lowest_points(m, d, geoms)[2]
        got = float(env.lowest_point(jnp.asarray(q, jnp.float32)))
        assert abs(got - want) < 1e-5, (got, want)
