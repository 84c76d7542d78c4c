"""Fail-state recovery (``tasks/recovery.py``, ``physics/falls.py``, ``evaluation/recovery.py``):
the point goal, its reward, the starts, the frozen clock and grace, the trials' success rule."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from conftest import jit_enabled
from jaxmotion.motion import MotionLib
from jaxmotion.motion import observations as O
from jaxmotion.physics import falls, sim
from jaxmotion.tasks import recovery as RC
from test_track import _env as track_env
from test_track import _moving_clip


def _frames(pos):
    pos = jnp.asarray(pos, jnp.float32)
    n = pos.shape[0]
    quat = jnp.tile(jnp.asarray([1.0, 0.0, 0.0, 0.0]), (n, 1))
    return O.LinkFrames(pos=pos, quat=quat, lin_vel=jnp.ones((n, 3)), ang_vel=2 * jnp.ones((n, 3)))


def _env(**rec):
    """``test_track``'s scene on a 2-s clip with recovery on (a 4-state fallen pool), no contact falls."""
    rc = RC.RecoveryConfig(enabled=True, pool_size=4, **rec)
    return track_env(clip=_moving_clip(60), recovery=rc, early_termination=False)


def test_far_goal_keeps_only_the_root_target_when_far():
    c = RC.RecoveryConfig(enabled=True)
    sim_f = _frames([[0.0, 0.0, 0.9], [0.0, 0.1, 1.2], [0.1, 0.0, 0.5]])
    near = _frames([[0.1, 0.0, 0.9], [0.5, 0.5, 1.5], [0.3, 0.3, 0.3]]).replace(lin_vel=jnp.zeros((3, 3)))
    out = RC.far_goal(near, sim_f, c)  # 0.1 m: within close_distance, the reference as it is
    for a, b in zip(jax.tree.leaves(out), jax.tree.leaves(near)):
        np.testing.assert_allclose(a, b)
    far = near.replace(pos=near.pos.at[0].set([1.0, 0.0, 0.9]))  # 1 m: the point goal
    out = RC.far_goal(far, sim_f, c)
    np.testing.assert_allclose(out.pos[0], [1.0, 0.0, 0.9])
    np.testing.assert_allclose(out.pos[1:], sim_f.pos[1:])
    np.testing.assert_allclose(out.lin_vel, sim_f.lin_vel)
    np.testing.assert_allclose(out.ang_vel, sim_f.ang_vel)
    very = near.replace(pos=near.pos.at[0].set([0.0, 8.0, 0.9]))  # 8 m: pulled onto 3 m
    np.testing.assert_allclose(RC.far_goal(very, sim_f, c).pos[0], [0.0, 3.0, 0.9], atol=1e-6)


def test_the_point_goal_reward_by_hand():
    c = RC.RecoveryConfig(enabled=True)
    r = lambda prev, d, im: float(RC.recovery_reward(jnp.float32(prev), jnp.float32(d), jnp.float32(im), c))
    assert r(2.0, 1.9, 0.8) == pytest.approx(9 * 0.1)  # far: no imitation part
    assert r(2.0, 2.1, 0.8) == pytest.approx(-9 * 0.1)  # moving away costs
    assert r(3.0, 2.0, 0.8) == pytest.approx(9 / 3)  # capped at a third of a metre per step
    assert r(0.25, 0.2, 0.8) == pytest.approx(9 * 0.05 + 0.4)  # close: half the imitation reward


def test_starts_fallen_far_or_as_the_reference():
    pool = jnp.asarray([[5.0, 5.0, 0.1, 1, 0, 0, 0] + [0.2] * 28], jnp.float32)
    qpos = jnp.tile(jnp.asarray([1.0, 2.0, 0.9, 1, 0, 0, 0] + [0.0] * 28, jnp.float32), (3, 1))
    qvel = jnp.ones((3, 34))
    key = jax.random.PRNGKey(3)
    base = RC.RecoveryConfig(enabled=True, fall_prob=0.0, far_prob=0.0)
    q, v, kind = RC.recovery_starts(key, qpos, qvel, pool, base)
    np.testing.assert_allclose(q, qpos)
    np.testing.assert_allclose(v, qvel)
    assert int(kind) == 0
    q, v, kind = RC.recovery_starts(key, qpos, qvel, pool, dataclasses.replace(base, fall_prob=1.0))
    assert int(kind) == RC.FALLEN
    np.testing.assert_allclose(q[:, :2], [[1.0, 2.0]] * 3)  # under the reference root
    np.testing.assert_allclose(q[:, 2:], jnp.tile(pool[0, 2:], (3, 1)))  # the pool's pose, the whole window
    np.testing.assert_allclose(v, 0.0)
    far = dataclasses.replace(base, far_prob=1.0, far_start=(3.0, 3.0))
    q, v, kind = RC.recovery_starts(key, qpos, qvel, pool, far)
    assert int(kind) == RC.FAR
    np.testing.assert_allclose(np.linalg.norm(q[:, :2] - qpos[:, :2], axis=-1), 3.0, rtol=1e-5)
    np.testing.assert_allclose(q[:, 2:], qpos[:, 2:])
    both = dataclasses.replace(far, fall_prob=1.0)
    assert int(RC.recovery_starts(key, qpos, qvel, pool, both)[2]) == RC.FALLEN | RC.FAR


def test_far_offsets_cover_the_annulus_uniformly():
    c = RC.RecoveryConfig(enabled=True, far_start=(0.0, 5.0))
    with jit_enabled():
        off = jax.jit(jax.vmap(lambda k: RC.far_offset(k, c)))(jax.random.split(jax.random.PRNGKey(0), 4000))
    r = np.linalg.norm(np.asarray(off), axis=-1)
    assert r.max() <= 5.0 + 1e-5
    assert np.mean(r < 2.5) == pytest.approx(0.25, abs=0.03)  # area fraction of the inner half-radius disk


def test_fallen_states_lie_on_the_ground_within_limits():
    cfg = sim.PhysicsConfig()
    pool = falls.fallen_states(cfg, 6, seed=0)
    again = falls.fallen_states(cfg, 6, seed=0)
    other = falls.fallen_states(cfg, 6, seed=1)
    assert pool.shape == (6, 35) and np.isfinite(pool).all()
    np.testing.assert_array_equal(pool, again)
    assert not np.allclose(pool, other)
    np.testing.assert_allclose(pool[:, :2], 0.0)
    assert (pool[:, 2] < 0.5).all()  # the pelvis is down (standing: ~0.9 m)
    np.testing.assert_allclose(np.linalg.norm(pool[:, 3:7], axis=-1), 1.0, atol=1e-5)
    m = sim.mj_model(cfg)
    lo, hi = m.jnt_range[m.actuator_trnid[:, 0]].T
    assert ((pool[:, 7:] >= lo - 0.1) & (pool[:, 7:] <= hi + 0.1)).all()


def test_a_fallen_start_freezes_the_clock_and_is_not_ended_during_its_grace():
    env = _env(fall_prob=1.0, far_prob=0.0, recovery_prob=0.0, recovery_steps=3)
    with jit_enabled():
        state, obs = jax.jit(env.reset_at)(jax.random.PRNGKey(0), jnp.int32(0), jnp.float32(0.5))
        assert float(state.data.qpos[2]) < 0.5 and np.isfinite(np.asarray(obs)).all()
        assert int(state.goal.rec.grace) == 3 and bool(state.goal.rec.frozen)
        step = jax.jit(lambda s: env.step(s, jnp.zeros(env.action_size), reset=(s, obs)))
        times, ended = [], []
        for _ in range(5):
            state, out = step(state)
            times.append(float(state.goal.time))
            ended.append(bool(out.terminated))
    # Three steps of grace with the clock standing at 0.5 s; then it runs, and the fallen body,
    # far from the reference, is ended by the distance rule (the episode restarts on ``reset``).
    assert times[:3] == pytest.approx([0.5, 0.5, 0.5])
    assert ended[:3] == [False, False, False]
    assert ended[3]


def test_an_episode_the_rule_would_end_goes_on_as_a_recovery_episode():
    env = _env(fall_prob=0.0, far_prob=1.0, far_start=(2.0, 2.0), recovery_prob=1.0, recovery_steps=2)
    task = env.task
    with jit_enabled():
        state, _ = jax.jit(env.reset_at)(jax.random.PRNGKey(1), jnp.int32(0), jnp.float32(0.2))
        goal = state.goal
        assert int(goal.rec.grace) == 2 and not bool(goal.rec.frozen)  # a far start: the clock runs
        frame = jax.jit(lambda g: task.reference(g, 0.0))(goal)
        far = frame.replace(pos=frame.pos + jnp.asarray([2.0, 0.0, 0.0]))
        step = jax.jit(lambda g, f: task.step(g, f, f, jax.random.PRNGKey(0)))
        outs = []
        for _ in range(4):
            out = step(goal, far)
            goal = out.goal
            outs.append(
                (bool(out.terminated), int(goal.rec.grace), bool(goal.rec.frozen), float(out.info["recovering"]))
            )
    # grace 2 -> 1 -> 0; then the rule would end it: a recovery episode instead (grace 2, frozen).
    assert outs[0][:2] == (False, 1) and outs[1][:2] == (False, 0)
    assert outs[2] == (False, 2, True, 1.0)
    assert outs[3][:3] == (False, 1, True)


def test_recovery_times_by_hand():
    from jaxmotion.evaluation.recovery import recovery_times

    err = np.asarray(
        [
            [0.4, 0.9, 0.9, 0.9],  # under 0.5 m only at the start, then up: not a recovery
            [0.9, 0.4, 0.9, 0.9],
            [0.9, 0.4, 0.4, 0.9],
            [0.9, 0.4, 0.4, 0.9],
            [0.9, 0.4, 0.4, 0.9],
        ]
    )
    times = recovery_times(err, dt=0.5, hold_steps=3)
    assert times[0] == np.inf
    assert times[1] == pytest.approx(1.0)  # err[t] follows step t + 1: back from the second step on
    assert times[2] == pytest.approx(1.5)  # back from the third step, held to the end: 3 steps
    assert times[3] == np.inf


def test_recovery_trials_report_every_scenario(data_dir, monkeypatch, tmp_path, capsys):
    """``eval --recovery`` end to end on a toy tracker, trials cut to 0.3 s: three scenarios, the
    far ones starting 3 m away, the fallen one lying under the reference, rates in [0, 1]."""
    import argparse
    import json

    from jaxmotion.evaluation import recovery as ev
    from test_track import tiny_tracker

    monkeypatch.setattr(ev, "TRIAL_SECONDS", 0.3)
    monkeypatch.setattr(ev, "HOLD_SECONDS", 0.1)
    learner = tiny_tracker(MotionLib.from_clips([_moving_clip()]))
    with jit_enabled():
        ts = learner.init(jax.random.PRNGKey(0))
        args = argparse.Namespace(trials=2, seed=0, recovery_pose=ev.POSE_CLIP, json=tmp_path / "r.json", video=None)
        assert ev.run(args, "toy", learner.cfg, learner, ts) == 0
    res = json.loads((tmp_path / "r.json").read_text())
    assert set(res["scenarios"]) == {"fallen", "far", "fallen+far"}
    s = res["scenarios"]
    assert s["far"]["start_error_m"] == pytest.approx(3.0, abs=0.05)  # the whole body moved 3 m
    assert 0.3 < s["fallen"]["start_error_m"] < 1.5
    assert all(0.0 <= v["succ_5s"] <= v["succ_10s"] <= 1.0 for v in s.values())
    assert all(v["closest_m"] <= min(v["start_error_m"], v["end_error_m"]) + 1e-6 for v in s.values())
    assert "Succ-10s" in capsys.readouterr().out


def test_the_tracking_evaluation_of_a_recovery_tracker_starts_every_clip_from_its_first_frame():
    """Mining and ``eval`` follow the protocol (every clip from t = 0, the reference state): a
    tracker trained with recovery keeps its goal features there but not its training starts."""
    from jaxmotion.evaluation.tracking import eval_env
    from test_track import tiny_tracker

    learner = tiny_tracker(MotionLib.from_clips([_moving_clip()]))
    rc = RC.RecoveryConfig(enabled=True, fall_prob=1.0, far_prob=1.0, pool_size=2)
    cfg = learner.cfg.env
    track = dataclasses.replace(cfg.task.track, recovery=rc)
    learner.cfg = dataclasses.replace(
        learner.cfg, env=dataclasses.replace(cfg, task=dataclasses.replace(cfg.task, track=track))
    )
    env = eval_env(learner)
    assert env.task.cfg.track.recovery.enabled and env.task.cfg.track.recovery.point_goal
    with jit_enabled():
        state, _ = jax.jit(env.reset_at)(jax.random.PRNGKey(0), jnp.int32(0), jnp.float32(0.0))
        ref = jax.jit(lambda g: env.task.reference(g, 0.0))(state.goal)
    assert int(state.goal.rec.grace) == 0
    # The root where the reference's is: not lying on the ground, not moved away (the joints may
    # differ by the scene's start clamping to the joint ranges).
    np.testing.assert_allclose(state.hist.pos[-1][0], ref.pos[0], atol=1e-5)
