"""Juggling: the throw/catch schedule, balls never lost, the reward and metrics by hand."""

from __future__ import annotations

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxmotion.tasks import juggle as J

DT = 1.0 / 30.0
HOME = np.array([[0.0, 0.2, 1.0], [0.0, -0.2, 1.0]], np.float32)  # left, right hand
V_STAR = J.target_speed(DT)


def _run(steps: int, catcher: bool):
    """Scripted hands: at home, moving up at v* (so every release is at the target speed).
    ``catcher`` teleports a hand onto its descending target ball, which catches it."""
    b = J.initial_balls(jnp.asarray(HOME))
    step = jax.jit(J.step_balls, static_argnums=4)
    hand_vel = jnp.tile(jnp.asarray([0.0, 0.0, V_STAR]), (2, 1))
    log = []
    for t in range(steps):
        hands = HOME.copy()
        if catcher:
            for h in (0, 1):
                i, pending = J.target_ball(b, h)
                nxt_p, nxt_v = J.fly(b.pos[i], b.vel[i], DT)
                if bool(pending) and float(nxt_v[2]) < 0:
                    hands[h] = np.asarray(nxt_p)
        b_new, thrown, caught, forced = step(b, jnp.asarray(t), jnp.asarray(hands), hand_vel, DT)
        r = J.hand_rewards(b_new, thrown, jnp.asarray(hands), hand_vel, jnp.asarray(t), DT, V_STAR)
        log.append(
            dict(
                t=t,
                thrower=np.asarray(b.to_hand)[np.asarray(thrown)],
                thrown=np.asarray(thrown),
                caught=np.asarray(caught),
                forced=np.asarray(forced),
                holder=np.asarray(b_new.holder),
                pos=np.asarray(b_new.pos),
                throw_at=np.asarray(b_new.throw_at),
                r=np.asarray(r),
            )
        )
        b = b_new
    return log


def test_target_speed_is_the_authors():
    assert pytest.approx(0.5 * 9.81 * 18 / 30) == V_STAR


@pytest.mark.parametrize("catcher", [False, True])
def test_throws_follow_the_schedule_and_balls_are_never_lost(catcher):
    log = _run(95, catcher)
    for e in log:
        t = e["t"]
        if t % 10 == 0:  # one throw every 10 steps, the hands alternating: left at 0, 20, ...
            assert e["thrown"].sum() == 1, t
            assert int(e["thrower"][0]) == (0 if t % 20 == 0 else 1), t
        else:
            assert e["thrown"].sum() == 0, t
        # Never lost: every ball is held or in flight above the floor, and due within 30 steps.
        assert np.isfinite(e["pos"]).all() and (e["pos"][:, 2] >= J.RADIUS - 1e-6).all()
        assert ((e["throw_at"] > t) & (e["throw_at"] <= t + 30)).all(), (t, e["throw_at"])
        # One step before a throw, the ball to throw is in its hand.
        due = e["throw_at"] == t + 1
        assert (e["holder"][due] >= 0).all(), t
    caught = sum(e["caught"].sum() for e in log)
    forced = sum(e["forced"].sum() for e in log)
    if catcher:  # a hand on the ball catches every throw
        assert caught >= 8 and forced == 0
    else:  # hands that never reach the ball: every ball is forced into the hand, flagged missed
        assert caught == 0 and forced == 7  # the throws at 0, 10, ..., 60 came due by step 94


def test_release_reward_by_hand():
    b = J.initial_balls(jnp.asarray(HOME))
    for frac, want in ((1.0, 1.0), (0.5, math.exp(-5 * 0.25)), (0.0, math.exp(-5.0))):
        vel = jnp.tile(jnp.asarray([0.0, 0.0, frac * V_STAR]), (2, 1))
        b1, thrown, _, _ = J.step_balls(b, jnp.asarray(0), jnp.asarray(HOME), vel, DT)
        r = J.hand_rewards(b1, thrown, jnp.asarray(HOME), vel, jnp.asarray(0), DT, V_STAR)
        assert bool(thrown[0]) and float(r[0]) == pytest.approx(want, rel=1e-5)  # the left hand threw
        assert float(r[1]) == 0.0  # before all three balls were released: no catch reward


def test_catch_reward_by_hand():
    """All released; the right hand's ball falls straight onto it: d = 0, dh = 0 -> 1.09; with the
    hand 0.3 m to the side (and 0.2 m low): the formula."""
    b = J.initial_balls(jnp.asarray(HOME))
    b = b.replace(
        released=jnp.ones(3, bool),
        holder=jnp.asarray([-1, 1, 0]),
        to_hand=jnp.asarray([1, 1, 0]),
        pos=jnp.asarray([[0.0, -0.2, 1.5], HOME[1], HOME[0]]),
        vel=jnp.zeros((3, 3)),
        release_h=jnp.asarray([1.0, 1.0, 1.0]),
        throw_at=jnp.asarray([20, 30, 40]),
    )
    none = jnp.zeros(3, bool)
    r = J.hand_rewards(b, none, jnp.asarray(HOME), jnp.zeros((2, 3)), jnp.asarray(5), DT, V_STAR)
    assert float(r[1]) == pytest.approx(0.1 + 0.9 * 1.1, rel=1e-5)
    assert float(r[0]) == pytest.approx(0.1 + 0.9 * 1.1, rel=1e-5)  # no pending ball: d = dh = 0
    hands = HOME.copy()
    hands[1] += [0.3, 0.0, -0.2]
    r = J.hand_rewards(b, none, jnp.asarray(hands), jnp.zeros((2, 3)), jnp.asarray(5), DT, V_STAR)
    d, dh = 0.3, 0.2  # the ball falls to 0.8 m, straight down
    want = 0.1 * math.exp(-20 * dh**2) + 0.9 * (0.9 * math.exp(-20 * d**2) + 0.2 * math.exp(-(d**2)))
    assert float(r[1]) == pytest.approx(want, rel=1e-4)
    # A missed ball pays only the height term.
    r = J.hand_rewards(
        b.replace(missed=jnp.asarray([True, False, False])),
        none,
        jnp.asarray(hands),
        jnp.zeros((2, 3)),
        jnp.asarray(5),
        DT,
        V_STAR,
    )
    assert float(r[1]) == pytest.approx(0.1 * math.exp(-20 * dh**2), rel=1e-4)


def test_landing_point_by_hand():
    p = J.landing_point(jnp.asarray([0.0, 0.0, 1.0]), jnp.asarray([1.0, 0.0, 2.0]), jnp.asarray(1.0), jnp.asarray(5.0))
    t = 2 * 2.0 / 9.81
    np.testing.assert_allclose(p, [t, 0.0, 1.0], atol=1e-5)
    # Capped by the time left.
    p = J.landing_point(jnp.asarray([0.0, 0.0, 1.0]), jnp.asarray([1.0, 0.0, 2.0]), jnp.asarray(1.0), jnp.asarray(0.1))
    np.testing.assert_allclose(p, [0.1, 0.0, 1.0 + 0.2 - 0.5 * 9.81 * 0.01], atol=1e-5)


def test_floor_stops_a_ball():
    p, v = J.fly(jnp.asarray([0.0, 0.0, 0.06]), jnp.asarray([1.0, 0.0, -3.0]), DT)
    assert float(p[2]) == pytest.approx(J.RADIUS) and float(jnp.abs(v).max()) == 0.0


def test_longest_streak():
    catches = np.array([[1, 0], [1, 1], [0, 1], [1, 1], [1, 0]])
    misses = np.array([[0, 0], [0, 0], [1, 0], [0, 0], [0, 1]])
    assert J.longest_streak(catches, misses) == 3  # episode 1: 1, 1, 1 before its miss


def test_task_reports_throws_and_release_error_in_a_scene_step():
    """The task's own step on link frames: the left hand releases at step 0 at 1 m/s upward."""
    from jaxmotion.motion.observations import LinkFrames
    from jaxmotion.physics.character import character as make_character
    from jaxmotion.tasks import TaskConfig, make_task

    class _Env:
        dt = DT
        character = make_character()

    task = make_task(TaskConfig(name="juggle+location"), _Env())
    nb = len(_Env.character.body_names)
    pos = np.zeros((nb, 3), np.float32)
    pos[0] = [0, 0, 0.9]
    vel = np.zeros((nb, 3), np.float32)
    vel[_Env.character.body_index("left_hand")] = [0, 0, 1.0]
    frame = LinkFrames(
        jnp.asarray(pos), jnp.tile(jnp.asarray([1.0, 0, 0, 0]), (nb, 1)), jnp.asarray(vel), jnp.zeros((nb, 3))
    )
    goal = task.init(jax.random.PRNGKey(0), frame)
    assert task.observe(goal, frame).shape == (task.goal_size,) == (23,)
    out = task.step(goal, frame, frame, jax.random.PRNGKey(1))
    assert int(out.info["throws"]) == 1
    assert float(out.info["release_error"]) == pytest.approx(V_STAR - 1.0, rel=1e-5)
    assert float(out.rewards[0]) == pytest.approx(0.5 * math.exp(-5 * (1.0 / V_STAR - 1) ** 2), rel=1e-5)
    info = jax.tree.map(lambda v: np.asarray(v)[None, None], out.info)
    s = task.summary(info, np.ones((1, 1), bool))
    assert s["release_speed_error_m_s"] == pytest.approx(V_STAR - 1.0, rel=1e-5)


def test_physical_balls_fly_in_the_scene_and_are_never_lost():
    """Three props in the MuJoCo scene: after a throw the physics flies the ball as the exact
    ballistic flight does (within MuJoCo's semi-implicit Euler, ~1.5 mm over a control step), the
    held balls are where the task has them, and every ball stays in the scene."""
    from conftest import jit_enabled
    from jaxmotion.envs.humanoid import EnvConfig, GroupConfig, HumanoidEnv
    from jaxmotion.motion import MotionLib, make_test_clip
    from jaxmotion.physics.props import PropConfig
    from jaxmotion.physics.sim import PhysicsConfig
    from jaxmotion.tasks import TaskConfig

    lib = MotionLib.from_clips([make_test_clip(20, 30.0, root_vel=(0.0, 0.0, 0.0), root_height=0.9)])
    balls = tuple(PropConfig(name=f"ball{i}", radius=J.RADIUS, restitution=0.0) for i in range(3))
    cfg = EnvConfig(
        physics=PhysicsConfig(props=balls),
        groups=(GroupConfig(name="full"),),
        policy_frames=2,
        early_termination=False,
        episode_steps=100,
        task=TaskConfig(name="juggle+location"),
    )
    env = HumanoidEnv(cfg, motion_libs=(lib,), init_lib=lib)
    with jit_enabled():
        reset, step = jax.jit(env.reset), jax.jit(env.step)
        state, _ = reset(jax.random.PRNGKey(0))
        np.testing.assert_allclose(state.data.qpos[-21:].reshape(3, 7)[:, :3], state.goal.balls.pos, atol=1e-6)
        hold = env.action_for_target(jnp.zeros(env.action_size))
        throws = 0
        for _t in range(45):
            before = state.goal.balls
            state, out = step(state, hold)
            b = state.goal.balls
            phys = np.asarray(state.data.qpos[-21:].reshape(3, 7)[:, :3])
            np.testing.assert_allclose(phys, b.pos, atol=1e-6)  # the scene holds the task's balls
            # A ball in flight for the whole step (free before and after, not just thrown, not
            # yet down) moved as the exact flight says.
            flying = (np.asarray(before.holder) < 0) & (np.asarray(b.holder) < 0) & (np.asarray(before.pos)[:, 2] > 0.3)
            for i in np.flatnonzero(flying):
                p, v = J.fly(before.pos[i], before.vel[i], DT)
                np.testing.assert_allclose(b.pos[i], p, atol=3e-3)
                np.testing.assert_allclose(b.vel[i], v, atol=3e-2)
            throws += int(out.info["throws"])
            # Not lost: above the floor (a ball thrown from a hand of the collapsing character
            # may start half inside it) and near the character.
            root = np.asarray(state.hist.pos[-1, 0])
            assert np.isfinite(phys).all() and (phys[:, 2] > 0).all()
            assert (np.linalg.norm(phys[:, :2] - root[:2], axis=-1) < 2.0).all()
    assert throws == 5  # at 0 (counted in step 1's schedule), 10, 20, 30, 40
