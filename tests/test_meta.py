"""Incremental learning (``training/meta.py``): a new policy on a frozen meta policy's sampled action."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from conftest import jit_enabled
from jaxmotion.training import checkpoint as ckpt
from jaxmotion.algos import ppo as PPO
from jaxmotion.envs.humanoid import EnvConfig, GroupConfig
from jaxmotion.training.meta import MetaError, goal_index, resolve_run
from jaxmotion.tasks import TaskConfig
from jaxmotion.training.learner import DiscConfig, Learner, NetConfig, PPOConfig, TrainConfig
from jaxmotion.training.runs import make_learner, spaces_mismatch
from jaxmotion.evaluation.imitation import meta_weight_summary
from jaxmotion.evaluation.rollout import rollout

WALK = ("compositemotion/locomotion/lafan1_walk1_subject1_100_1170.json",)
AIM = ("compositemotion/aiming/lafan1_aiming2_subject3_140_970.json",)


def _cfg(task: str, groups, **kw) -> TrainConfig:
    env = EnvConfig(init_motions=WALK, groups=groups, episode_steps=20, policy_frames=2, task=TaskConfig(name=task))
    return TrainConfig(
        env=env,
        net=NetConfig(policy_hidden=(32, 32), critic_hidden=(32, 32), disc_hidden=(16, 16), disc_heads=2),
        ppo=PPOConfig(num_envs=8, horizon=4, minibatch_size=16, epochs=1),
        disc=DiscConfig(minibatch_size=16),
        iterations=1,
        chunk=1,
        **kw,
    )


@pytest.fixture(scope="module")
def meta_run(tmp_path_factory, data_dir):
    """A run folder holding an (untrained) target-location policy: a meta policy to build on."""
    run = tmp_path_factory.mktemp("runs") / "goal" / "location_walk" / "20260101-000000"
    cfg = _cfg("location", (GroupConfig(name="full", motions=WALK),))
    with jit_enabled():
        learner = make_learner(cfg)
        ts = learner.init(jax.random.PRNGKey(7))
    # A policy whose actions are far from zero, so that "follows the meta policy" is visible.
    mean = ts.policy_params["params"]["mean"]
    params = {"params": {**ts.policy_params["params"], "mean": {**mean, "kernel": 20.0 * mean["kernel"]}}}
    ts = ts.replace(policy_params=params)
    ckpt.write_config(run, "goal/location_walk", cfg)
    mgr = ckpt.manager(run)
    ckpt.save(mgr, 1, ts)
    mgr.close()
    return run


@pytest.fixture(scope="module")
def incremental(meta_run):
    cfg = _cfg(
        "aim+location",
        (GroupConfig(name="upper", motions=AIM, frames=2), GroupConfig(name="lower", motions=WALK)),
        meta=str(meta_run.parent),
    )  # a folder of runs: its newest is taken
    with jit_enabled():
        learner = make_learner(cfg)
        ts = learner.init(jax.random.PRNGKey(0))
    return learner, ts


def test_goal_blocks_are_found_by_name():
    parts = (("location", 4), ("aim", 3))
    np.testing.assert_array_equal(goal_index((("location", 4),), parts), [0, 1, 2, 3])
    np.testing.assert_array_equal(goal_index((("aim", 3),), parts), [4, 5, 6])
    np.testing.assert_array_equal(goal_index((), parts), np.zeros(0))
    with pytest.raises(ValueError, match="heading"):
        goal_index((("heading", 3),), parts)


def test_meta_run_must_exist(tmp_path):
    with pytest.raises(MetaError, match="meta=.*train that run first"):
        resolve_run(tmp_path)
    # The CLI says so in one line instead of a traceback.
    from jaxmotion import train as T

    assert T.main(["incremental/aim+walk", f"meta={tmp_path}"]) == 2


def test_incremental_policy_starts_as_its_meta_policy(incremental, meta_run):
    learner, ts = incremental
    assert learner.meta.run_dir == meta_run
    obs = ts.obs
    with jit_enabled():
        a, _, a_meta = jax.jit(lambda o: learner.act(ts, o, None))(obs)
        w = jax.jit(lambda o: learner.policy_weights(ts, o))(obs)
        # The meta policy acts on its own slice: the body state and the location block of the goal.
        body = learner.env.body_obs_size
        ref = jax.jit(lambda o: learner.meta.learner.act(ts.meta, o, None)[0])(obs[:, : body + 4])
    np.testing.assert_allclose(a_meta, ref, atol=1e-6)
    np.testing.assert_allclose(w, 1 / (1 + np.exp(-3.0)), atol=1e-3)
    assert float(jnp.abs(a_meta).mean()) > 0.3  # a meta policy that acts
    np.testing.assert_allclose(a, w * a_meta, atol=0.01)  # mu starts near 0


def test_rollout_stores_the_meta_action_and_updates_leave_the_meta_policy_frozen(incremental):
    learner, ts = incremental
    with jit_enabled():
        ts1, traj = jax.jit(learner.rollout)(ts)
        T, B = traj.terminated.shape
        assert traj.extra.shape == (T, B, learner.env.action_size)
        # The stored log-probs are those of the policy at the stored meta actions (PPO ratio 1).
        flat = lambda x: x.reshape((T * B,) + x.shape[2:])

        def logp(ts, traj):
            nobs = learner.normalize_obs(ts.obs_norm, flat(traj.obs))
            mean, log_std = learner.policy.dist(ts.policy_params, nobs, flat(traj.extra))
            return PPO.gaussian_log_prob(mean, log_std, flat(traj.action))

        np.testing.assert_allclose(jax.jit(logp)(ts, traj), flat(traj.log_prob), atol=1e-4)
        ts2, _ = jax.jit(learner.iteration)(ts)
    for a, b in zip(jax.tree.leaves(ts2.meta), jax.tree.leaves(ts.meta)):
        np.testing.assert_array_equal(a, b)
    moved = [
        not np.array_equal(a, b) for a, b in zip(jax.tree.leaves(ts2.policy_params), jax.tree.leaves(ts.policy_params))
    ]
    assert any(moved)


def test_eval_reports_and_plots_the_meta_weights(incremental, tmp_path):
    from jaxmotion.viz.plot import plot_meta_weights

    learner, ts = incremental
    with jit_enabled():
        ro = rollout(learner, ts, episodes=2, steps=6)
    assert ro["meta_w"].shape == (6, 2, learner.env.action_size)
    summary = meta_weight_summary(learner, ro)
    assert set(summary["group_mean"]) == {"upper", "lower"}
    assert summary["mean"] == pytest.approx(1 / (1 + np.exp(-3.0)), abs=1e-3)
    assert len(summary["dof"]) == learner.env.action_size
    out = plot_meta_weights(learner, ro, tmp_path / "w.png")
    assert out.stat().st_size > 1000


def test_meta_policy_with_another_history_length_is_a_clear_error(meta_run):
    cfg = _cfg("aim+location", (GroupConfig(name="lower", motions=WALK),), meta=str(meta_run))
    cfg = dataclasses.replace(cfg, env=dataclasses.replace(cfg.env, policy_frames=3))
    with jit_enabled(), pytest.raises(ValueError, match="frames of body state"):
        make_learner(cfg)


def test_an_incremental_and_a_plain_run_take_turns_each_with_its_own_networks(incremental):
    """eval --switch between runs that share spaces but not networks (one has a meta policy):
    each acts through its own learner; before the first switch it is the incremental run alone."""

    learner, ts = incremental
    plain_cfg = _cfg(
        "aim+location", (GroupConfig(name="upper", motions=AIM, frames=2), GroupConfig(name="lower", motions=WALK))
    )
    with jit_enabled():
        plain = Learner(plain_cfg)
        plain_ts = plain.init(jax.random.PRNGKey(1))
        assert spaces_mismatch([("inc", learner), ("plain", plain)]) is None
        ro = rollout(learner, (ts, plain_ts), episodes=2, steps=5, switch_steps=2, actors=(learner, plain))
        alone = rollout(learner, ts, episodes=2, steps=5)
    np.testing.assert_array_equal(ro["acting"][:, 0], [0, 0, 1, 1, 0, 0])
    assert np.isfinite(ro["qpos"]).all()
    np.testing.assert_allclose(ro["qpos"][:3], alone["qpos"][:3], atol=1e-5)
    assert not np.allclose(ro["qpos"][4], alone["qpos"][4], atol=1e-4)


def test_play_acts_each_run_through_its_own_learner(incremental):
    """``python -m jaxmotion.play inc plain``: keys switch between an incremental run (meta policy)
    and a plain one; each acts through its own networks, from the same character state."""
    from jaxmotion.viz import play

    learner, ts = incremental
    plain = Learner(
        _cfg(
            "aim+location", (GroupConfig(name="upper", motions=AIM, frames=2), GroupConfig(name="lower", motions=WALK))
        )
    )
    with jit_enabled():
        plain_ts = plain.init(jax.random.PRNGKey(1))
        p = play.Player(learner, [ts, plain_ts], seed=0, actors=[learner, plain])
        before = p.state
        qpos_inc, _, _ = p.tick()
        p.key(ord("2"))
        from_before = p._steps[1](plain_ts, before, jnp.zeros(2), jnp.zeros(()))[1]
        mid = p.state
        qpos_plain, _, _ = p.tick()
        want = p._steps[1](plain_ts, mid, jnp.zeros(2), jnp.zeros(()))[1]
    assert p._steps[0] is not p._steps[1]
    np.testing.assert_allclose(qpos_plain, want, atol=1e-6)
    assert not np.allclose(qpos_inc, from_before, atol=1e-4)  # the two runs act differently
    with pytest.raises(ValueError, match="learners"):
        play.Player(learner, [ts, plain_ts], actors=[learner])


def test_meta_weight_head_gets_its_own_learning_rate(incremental, meta_run):
    """ppo.meta_weight_lr: Adam's first step moves the w head by its own rate, the rest of the
    policy by actor_lr and the critic by critic_lr (each step of Adam is about its rate)."""
    learner, ts = incremental
    cfg = dataclasses.replace(learner.cfg, ppo=dataclasses.replace(learner.cfg.ppo, meta_weight_lr=1e-2))
    params = {"actor": ts.policy_params, "critic": ts.critic_params}
    grads = jax.tree.map(jnp.ones_like, params)
    for lr_w, lrn in ((1e-2, make_learner(cfg)), (learner.cfg.ppo.actor_lr, learner)):
        updates, _ = lrn.optimizer.update(grads, lrn.optimizer.init(params), params)
        actor = updates["actor"]["params"]
        for name, leaf in actor.items():
            want = lr_w if name == "meta_weight" else learner.cfg.ppo.actor_lr
            for x in jax.tree.leaves(leaf):
                np.testing.assert_allclose(x, -want, rtol=1e-3)
        for x in jax.tree.leaves(updates["critic"]):
            np.testing.assert_allclose(x, -learner.cfg.ppo.critic_lr, rtol=1e-3)
