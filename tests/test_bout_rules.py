"""Bout rules without physics: fencing's closeness at the start, boxing's hit onsets, the round
length of the sports experiments, and the evaluator's falls per minute."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from conftest import REPO, jit_enabled
from jaxmotion.config import load_experiment
from jaxmotion.evaluation.bouts import print_summary, summarize
from jaxmotion.tasks import TaskConfig
from test_bout import _env, _frames


def _rotate(q: np.ndarray, v: np.ndarray) -> np.ndarray:
    """v rotated by the unit quaternion q (wxyz), by hand."""
    w, u = q[0], q[1:]
    return v + 2.0 * np.cross(u, np.cross(u, v) + w * v)


def test_fencing_closeness_is_visible_at_the_default_start():
    """At the default 4-m start the blade points are ~3.3 m from the opponent's targets: the
    authors' exp(-3 d) is ~5e-5, the paper's exp(-3 d^2) ~1e-14 (below the advantage eps, 1e-8)."""
    env = _env("fencing")
    task = env.task
    assert not task.sub.close_squared and task.sub.close_k == 3.0 and task.sub.start_distance == 4.0
    xy, yaw = task.start(jax.random.PRNGKey(0))
    f = _frames(env, np.asarray(xy), np.asarray(yaw))
    ch = env.character
    pos, quat = np.asarray(f.pos, np.float64), np.asarray(f.quat, np.float64)
    sword, torso, pelvis = (ch.body_index(b) for b in ("sword", "torso", "pelvis"))
    d = []
    for k in range(2):
        blade = [pos[k, sword] + _rotate(quat[k, sword], np.array([-x, 0.0, 0.0])) for x in (0.0, 0.2, 0.4)]
        op = 1 - k
        targets = [
            pos[op, torso] + _rotate(quat[op, torso], np.array([0.0, 0.0, 0.12])),
            pos[op, pelvis] + _rotate(quat[op, pelvis], np.array([0.0, 0.0, 0.205])),
        ]
        d.append(min(np.linalg.norm(b - t) for b in blade for t in targets))
    d = np.asarray(d)
    assert np.all((d > 2.5) & (d < 4.0)), d
    qv = jnp.zeros((2, env.layout.nv))
    out = task.step(task.init(None, f), f, f, jnp.zeros(2), jnp.zeros(2, bool), qv, qv, jnp.asarray(1), None)
    close = np.asarray(out.info["close"])
    np.testing.assert_allclose(close, np.exp(-3.0 * d), rtol=1e-3)
    np.testing.assert_allclose(np.asarray(out.rewards[:, 1]), close)
    assert np.all(close > 2e-5), close
    # The players' root distance is logged (task/distance), so a run shows whether fencers close in.
    np.testing.assert_allclose(np.asarray(out.info["distance"]), task.sub.start_distance, rtol=1e-5)
    # The paper's squared kernel at the same start: nothing to learn from.
    env_sq = _env("fencing", task=TaskConfig(name="fencing", fencing=dataclasses.replace(task.sub, close_squared=True)))
    sq = np.asarray(env_sq.task.close_reward(f))
    np.testing.assert_allclose(sq, np.exp(-3.0 * d**2), rtol=1e-2)
    assert np.all(sq < 1e-10), sq


def _boxing_run(forces: np.ndarray, **boxing) -> tuple[np.ndarray, np.ndarray]:
    """Runs the boxing task over scoring forces [T, 2] with the players 3 m apart (no other
    rule fires); returns the match rewards [T, 2] and the counted hits [T, 2]."""
    task_cfg = TaskConfig(name="boxing", boxing=dataclasses.replace(TaskConfig().boxing, **boxing))
    env = _env("boxing", task=task_cfg)
    task = env.task
    f = _frames(env, [[-1.5, 0.0], [1.5, 0.0]])
    qv = jnp.zeros((2, env.layout.nv))
    with jit_enabled():
        step = jax.jit(lambda g, x, t: task.step(g, f, f, x, jnp.zeros(2, bool), qv, qv, t, None))
    g = task.init(None, f)
    np.testing.assert_array_equal(g.hit_wait, [0, 0])
    match, hit = [], []
    for t, x in enumerate(np.asarray(forces, np.float32), 1):
        with jit_enabled():
            out = step(g, jnp.asarray(x), jnp.asarray(t))
        g = out.goal
        match.append(np.asarray(out.rewards[:, 0]))
        hit.append(np.asarray(out.info["hit"]))
    return np.asarray(match), np.asarray(hit)


def test_a_held_contact_pays_once_per_half_second():
    forces = np.zeros((40, 2))
    forces[:20, 0] = 150.0  # player 0's glove held on player 1's chest for 20 steps (0.67 s)
    match, hit = _boxing_run(forces)
    assert np.flatnonzero(hit[:, 0]).tolist() == [0, 15]  # steps 1 and 16: 0.5 s at 30 Hz apart
    assert not hit[:, 1].any()
    np.testing.assert_allclose(match[[0, 15]], [[150.0, -150.0]] * 2)
    assert match.sum(0).tolist() == [300.0, -300.0]  # per step it would have been 3000
    # The paper's Eq. 2 read literally (interval 0): every step of contact pays.
    match0, hit0 = _boxing_run(forces, touch_interval=0.0)
    assert hit0[:20, 0].all() and not hit0[20:].any()
    assert match0.sum(0).tolist() == [3000.0, -3000.0]


def test_two_touches_a_second_apart_pay_twice_and_each_player_waits_alone():
    forces = np.zeros((45, 2))
    forces[0:3, 0] = 80.0  # a touch of 3 steps
    forces[30:33, 0] = 300.0  # another, 1 s later (clipped at 200 N)
    forces[5:8, 1] = 50.0  # the opponent's hit, inside player 0's wait
    forces[12, 1] = 60.0  # and one inside its own wait: not counted
    match, hit = _boxing_run(forces)
    assert np.flatnonzero(hit[:, 0]).tolist() == [0, 30]
    assert np.flatnonzero(hit[:, 1]).tolist() == [5]
    np.testing.assert_allclose(match[0], [80.0, -80.0])
    np.testing.assert_allclose(match[5], [-50.0, 50.0])
    np.testing.assert_allclose(match[30], [200.0, -200.0])
    np.testing.assert_allclose(match.sum(0), [230.0, -230.0])


def test_sports_experiments_rounds():
    exp = REPO / "experiments"
    for name, steps in (("boxing/selfplay", 1800), ("boxing/selfplay_meta", 1800), ("fencing/selfplay", 600)):
        cfg = load_experiment(name, exp)
        assert cfg.env.physics.control_hz == 30.0 and cfg.env.episode_steps == steps, name
        assert cfg.env.task.boxing.touch_interval == 0.5 and not cfg.env.task.fencing.close_squared


def test_falls_per_minute_over_the_minutes_played(capsys):
    oc = {
        "score": np.array([1, -1, 0, 1]),
        "length_s": np.array([60.0, 30.0, 15.0, 15.0]),  # 2 minutes in all
        "fall_me": np.array([False, True, True, False]),
        "fall_op": np.array([True, False, False, False]),
        "penalty_me": np.array([False, True, True, False]),
        "penalty_op": np.array([True, False, False, False]),
        "damage_diff": np.array([10.0, -5.0, 0.0, 3.0]),
        "hits_me": np.array([2, 0, 0, 1]),
        "hits_op": np.array([0, 1, 0, 0]),
    }
    res = summarize("boxing", oc)
    assert res["minutes_played"] == pytest.approx(2.0)
    assert res["falls"] == {"self": 2, "opponent": 1}
    assert res["falls_per_minute"] == pytest.approx({"self": 1.0, "opponent": 0.5})
    print_summary("vs itself", {**res, "round_s": 60.0}, "boxing")
    line = capsys.readouterr().out
    assert "falls 2/1 (1.00/0.50 a minute)" in line and "(round 60 s)" in line
