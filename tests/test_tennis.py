"""Props and the tennis task: the ball as a free body of the scene (bounces off the racket and the
floor, passes through the body) on both physics backends, the hit reward and landing point by
hand, the feeding schedule, and a quick check of the task in its scene."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from conftest import jit_enabled
from jaxmotion.envs.humanoid import EnvConfig, GroupConfig, HumanoidEnv
from jaxmotion.motion import MotionLib, make_test_clip
from jaxmotion.physics.props import PropConfig
from jaxmotion.physics.sim import PhysicsConfig
from jaxmotion.tasks import TaskConfig, TennisConfig
from jaxmotion.tasks.tennis import G, hit_reward, landing_point


def _env(backend="mujoco", **tennis) -> HumanoidEnv:
    lib = MotionLib.from_clips([make_test_clip(20, 30.0, root_vel=(0.0, 0.0, 0.0), root_height=0.9, sword_shield=True)])
    cfg = EnvConfig(
        physics=PhysicsConfig(sword_shield=True, racket=True, props=(PropConfig(),), backend=backend, sim_hz=240.0),
        groups=(GroupConfig(name="upper"), GroupConfig(name="lower")),
        episode_steps=200,
        policy_frames=2,
        early_termination=False,
        task=TaskConfig(name="tennis", tennis=TennisConfig(**tennis)),
    )
    return HumanoidEnv(cfg, motion_libs=(lib, lib), init_lib=lib)


@pytest.fixture(scope="module")
def env():
    return _env()


def test_landing_point_and_hit_reward_by_hand():
    r = 0.033
    # 1.25 m above the floor (centre 1.25 + r), 8 m/s along x: lands after sqrt(2 * 1.25 / g) s.
    land = landing_point(jnp.asarray([1.0, 2.0, 1.25 + r]), jnp.asarray([8.0, 0.0, 0.0]), r)
    np.testing.assert_allclose(land, [1.0 + 8.0 * math.sqrt(2.5 / G), 2.0], rtol=1e-5)
    # Thrown up at 3 m/s from the floor: back after 2 * 3 / g s.
    land = landing_point(jnp.asarray([0.0, 0.0, r]), jnp.asarray([0.0, 4.0, 3.0]), r)
    np.testing.assert_allclose(land, [0.0, 4.0 * 6.0 / G], rtol=1e-5, atol=1e-6)
    tgt = jnp.asarray([10.0, 0.0])
    assert float(hit_reward(jnp.asarray([10.0, 0.0, 0.0]), tgt, tgt, 10.0, 2.0)) == pytest.approx(1.0)
    assert float(hit_reward(jnp.asarray([30.0, 0.0, 0.0]), tgt, tgt, 10.0, 2.0)) == pytest.approx(1.0)
    # Half the speed, landing 2 sigma away: 0.5 * 0.5 + 0.5 * exp(-2).
    got = hit_reward(jnp.asarray([0.0, 3.0, 4.0]), tgt + jnp.asarray([0.0, 4.0]), tgt, 10.0, 2.0)
    assert float(got) == pytest.approx(0.25 + 0.5 * math.exp(-2.0), rel=1e-6)


def test_racket_needs_the_sword_character_and_tennis_a_ball():
    with pytest.raises(ValueError, match="sword_shield"):
        HumanoidEnv(EnvConfig(physics=PhysicsConfig(racket=True)))
    lib = MotionLib.from_clips([make_test_clip(10, 30.0, sword_shield=True)])
    cfg = EnvConfig(physics=PhysicsConfig(sword_shield=True, racket=True, sim_hz=240.0), task=TaskConfig(name="tennis"))
    with pytest.raises(ValueError, match="one ball"):
        HumanoidEnv(cfg, motion_libs=(lib,), init_lib=lib)
    cfg = EnvConfig(
        physics=PhysicsConfig(sword_shield=True, racket=True, props=(PropConfig(),)), task=TaskConfig(name="tennis")
    )
    with pytest.raises(ValueError, match="passes through the racket"):
        HumanoidEnv(cfg, motion_libs=(lib,), init_lib=lib)


def _hold(env):
    """The action whose PD target is the zero pose the test clip stands in."""
    return env.action_for_target(jnp.zeros(env.action_size))


def _with_ball(env, state, pos, vel):
    goal = state.goal.replace(
        ball_pos=jnp.asarray(pos, jnp.float32), ball_vel=jnp.asarray(vel, jnp.float32), feed=jnp.ones((), bool)
    )
    return state.replace(data=env.place_props(state.data, goal), goal=goal.replace(feed=jnp.zeros((), bool)))


@pytest.mark.parametrize("backend", ["mujoco", "mjx"])
def test_ball_bounces_off_the_racket_and_scores_a_hit(backend):
    env = _env(backend)
    with jit_enabled():
        reset, step = jax.jit(env.reset), jax.jit(env.step)
        state, _ = reset(jax.random.PRNGKey(0))
        head = env.task.head(jax.tree.map(lambda x: x[-1], state.hist))
        # The racket's face is horizontal in the zero pose: drop the ball onto its centre.
        state = _with_ball(env, state, head + jnp.asarray([0.0, 0.0, 0.1]), [0.0, 0.0, -4.0])
        forces, vz, rewards, hits = [], [], [], []
        for _ in range(4):
            state, out = step(state, _hold(env))
            forces.append(float(state.goal.force))
            vz.append(float(state.goal.ball_vel[2]))
            rewards.append(float(out.task_reward[0]))
            hits.append(bool(state.goal.hit))
    assert forces[0] > env.cfg.task.tennis.touch_force, forces  # struck within the first control step
    assert max(vz) > 1.0, vz  # it flies back up
    assert hits[0] and sum(r > 0 for r in rewards) == 1, (hits, rewards)  # one hit, paid once


def test_ball_passes_through_the_body_and_feeds_on_schedule():
    env = _env(feed_every=5)
    with jit_enabled():
        reset, step = jax.jit(env.reset), jax.jit(env.step)
        state, _ = reset(jax.random.PRNGKey(1))
        frame = jax.tree.map(lambda x: x[-1], state.hist)
        torso = frame.pos[env.character.body_index("torso")]
        state = _with_ball(env, state, torso - jnp.asarray([0.3, 0.0, 0.0]), [6.0, 0.0, 0.0])
        state, out = step(state, _hold(env))
        # Through the torso without touching it: still 6 m/s along x, and no hit.
        np.testing.assert_allclose(state.goal.ball_vel[0], 6.0, rtol=1e-4)
        assert float(state.goal.force) == 0.0 and not bool(state.goal.hit)
        fed = []
        for _t in range(2, 12):
            state, out = step(state, _hold(env))
            fed.append(bool(out.info["fed"]))
            if fed[-1]:
                # The new ball is where the task put it, in the physics state and the goal alike,
                # beside the character on its racket side (the root's right, -y here).
                ball = np.asarray(state.data.qpos[-7:-4])
                np.testing.assert_allclose(ball, state.goal.ball_pos, atol=1e-6)
                c = env.cfg.task.tennis
                root = np.asarray(state.hist.pos[-1, 0])
                assert c.feed_forward[0] - 0.1 <= ball[0] - root[0] <= c.feed_forward[1] + 0.1
                assert -c.feed_right[1] - 0.1 <= ball[1] - root[1] <= -c.feed_right[0] + 0.1
    assert fed == [t % 5 == 0 for t in range(2, 12)], fed


def test_tennis_scene_quick_check(env):
    """Jitted, vmapped reset and random steps: shapes, no NaN, rewards in [0, 1], metrics."""
    with jit_enabled():
        reset, step = jax.jit(jax.vmap(env.reset)), jax.jit(jax.vmap(env.step))
        state, obs = reset(jax.random.split(jax.random.PRNGKey(2), 3))
        assert obs.shape == (3, env.obs_size) and env.task.goal_size == 10
        infos = []
        rng = jax.random.PRNGKey(3)
        for _ in range(6):
            rng, k = jax.random.split(rng)
            state, out = step(state, 0.3 * jax.random.normal(k, (3, env.action_size)))
            assert bool(jnp.isfinite(out.obs).all()) and out.task_reward.shape == (3, 2)
            assert bool(((out.task_reward >= 0) & (out.task_reward <= 1)).all())
            infos.append(out.info)
    info = jax.tree.map(lambda *x: np.stack(x), *infos)
    summary = env.task.summary(info, np.ones((6, 3), bool))
    assert set(summary) >= {"hit_rate", "out_speed_m_s", "landing_error_m", "reach_m"}
    assert summary["reach_m"] > 0
