"""Self-play with one policy per player (``player_policies='separate'``): each player acts with its
own policy and is trained on its own transitions only, so two players that see the same thing but
want different things both get what they want, which one shared policy cannot do.

The learner is tested on a tiny two-player env of its own (``Duel``) that keeps to the env
interface the learner uses, so these tests run in seconds; the real bouts (``tests/test_bout.py``)
use the same code path."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from flax import struct

from conftest import jit_enabled
from jaxmotion.envs.humanoid import EnvConfig, StepOut
from jaxmotion.training.loop import make_mesh, make_train_chunk, shard_state
from jaxmotion.training.learner import Learner, NetConfig, PPOConfig, TrainConfig, agent_of

TARGETS = (0.5, -0.5)


@struct.dataclass
class DuelState:
    x: jax.Array  # [2] each player's position on a line
    steps: jax.Array


class _DuelTask:
    reward_names = ("target",)
    min_reward = -4.0

    @staticmethod
    def weights():
        return (1.0,)


class Duel:
    """Two players on a line, each observing only its own position; player p is paid
    ``-(x_p - TARGETS[p])^2``. Both see the same kind of observation, so only separate policies
    can send them to different targets."""

    players = 2
    body_obs_size = 1
    obs_size = 1
    action_size = 1
    task = _DuelTask()
    steps = 10

    def __init__(self, cfg: EnvConfig):
        self.cfg = cfg

    def disc_obs_sizes(self):
        return ()

    def ref_disc_obs(self, rng, n):
        return ()

    def reset(self, rng, clip_weight=None):
        s = DuelState(x=jax.random.uniform(rng, (2,), minval=-0.2, maxval=0.2), steps=jnp.zeros((), jnp.int32))
        return s, s.x[:, None]

    def step(self, state: DuelState, action, reset=None):
        x = jnp.clip(state.x + 0.1 * jnp.clip(action[:, 0], -1.0, 1.0), -1.0, 1.0)
        steps = state.steps + 1
        reward = -jnp.square(x - jnp.asarray(TARGETS))[:, None]
        done = steps >= self.steps
        new = DuelState(x=x, steps=steps)
        out_state = jax.tree.map(lambda a, b: jnp.where(done, a, b), reset[0], new)
        false = jnp.zeros((2,), bool)
        return out_state, StepOut(
            obs=jnp.where(done, reset[1], x[:, None]),
            final_obs=x[:, None],
            disc_obs=(),
            terminated=false,
            truncated=jnp.broadcast_to(done, (2,)),
            unstable=false,
            task_reward=reward,
            info={},
        )


def _learner(player_policies: str = "separate", **ppo) -> Learner:
    env_cfg = EnvConfig(groups=(), players=2)
    ppo = dict(
        dict(
            num_envs=16,
            horizon=8,
            minibatch_size=64,
            epochs=4,
            actor_lr=3e-3,
            critic_lr=3e-3,
            terminate_reward=None,
            absorbing_termination=False,
        ),
        **ppo,
    )
    cfg = TrainConfig(
        env=env_cfg,
        net=NetConfig(policy_hidden=(16,), critic_hidden=(16,), init_log_std=-1.0, state_dependent_std=False),
        ppo=PPOConfig(**ppo),
        player_policies=player_policies,
    )
    return Learner(cfg, env=Duel(env_cfg))


def _leaves_equal(a, b) -> bool:
    return all(np.array_equal(np.asarray(x), np.asarray(y)) for x, y in zip(jax.tree.leaves(a), jax.tree.leaves(b)))


def test_each_player_acts_with_its_own_policy():
    learner = _learner()
    ts = learner.init(jax.random.PRNGKey(0))
    assert not _leaves_equal(agent_of(ts, 0).policy_params, agent_of(ts, 1).policy_params)
    obs = jnp.tile(jnp.linspace(-0.5, 0.5, 5)[:, None, None], (1, 2, 1))  # both players see the same
    a, logp, _ = learner.act(ts, obs, None)
    assert a.shape == (5, 2, 1) and logp.shape == (5, 2)
    for p in range(2):
        mine, _, _ = learner._act(agent_of(ts, p), obs[:, p], None)
        np.testing.assert_allclose(a[:, p], mine, rtol=1e-6, atol=1e-6)
    assert not np.allclose(a[:, 0], a[:, 1])
    a, logp, _ = learner.act(ts, obs, jax.random.PRNGKey(1))
    assert np.all(np.isfinite(np.asarray(logp)))


def test_each_player_learns_from_its_own_transitions_only():
    learner = _learner(epochs=1)
    ts = learner.init(jax.random.PRNGKey(0))
    ts, traj = learner.rollout(ts)
    assert traj.obs.shape == (8, 16, 2, 1)  # [T, B, P, ...]: kept apart for the players' updates
    rewards = jax.random.normal(jax.random.PRNGKey(2), traj.terminated.shape + (1,))
    new, m = learner.ppo_step_players(ts, traj, rewards)
    # Other rewards for player 1 only: player 0's update is unchanged, player 1's is not.
    other, _ = learner.ppo_step_players(ts, traj, rewards.at[:, :, 1].multiply(-3.0))
    assert all(np.all(np.isfinite(np.asarray(v))) for v in jax.tree.leaves(m))
    for p in range(2):
        assert not _leaves_equal(agent_of(new, p).policy_params, agent_of(ts, p).policy_params)
    for f in ("policy_params", "critic_params", "popart", "opt_state"):
        assert _leaves_equal(getattr(agent_of(new, 0), f), getattr(agent_of(other, 0), f)), f
    assert not _leaves_equal(agent_of(new, 1).policy_params, agent_of(other, 1).policy_params)


def test_observation_statistics_are_per_player():
    learner = _learner()
    ts = learner.init(jax.random.PRNGKey(0))
    _, traj = learner.rollout(ts)
    traj = traj.replace(obs=traj.obs.at[:, :, 1].add(10.0))
    norm = learner.update_obs_norm(ts.obs_norm, traj)
    assert norm.count.shape == (2,)
    for p in range(2):  # a fresh normaliser's mean is the mean of that player's observations
        np.testing.assert_allclose(norm.mean[p], np.mean(np.asarray(traj.obs[:, :, p]), (0, 1)), rtol=1e-4)
    assert float(norm.mean[1, 0] - norm.mean[0, 0]) > 9.0


def test_separate_policies_reach_targets_a_shared_policy_cannot():
    """Same seeds, same budget: separate policies send each player to its own target; the shared
    policy, which cannot tell the players apart, at best stays between them (reward about -0.25)."""

    def final_reward(player_policies):
        learner = _learner(player_policies)
        with jit_enabled():
            mesh = make_mesh(jax.devices()[:1])
            ts = shard_state(learner.init(jax.random.PRNGKey(0)), mesh)
            chunk = make_train_chunk(learner, mesh, 20, ts)
            for _ in range(3):
                ts, m = chunk(ts)
        return float(np.mean(np.asarray(m["reward/target"])[-5:]))

    separate, shared = final_reward("separate"), final_reward("shared")
    print(f"mean reward over the last 5 of 60 iterations: separate {separate:.3f}, shared {shared:.3f}")
    assert shared < -0.15
    assert separate > shared + 0.1


def test_separate_policies_need_two_players():
    from jaxmotion.envs.humanoid import GroupConfig, HumanoidEnv
    from jaxmotion.motion import MotionLib, make_test_clip

    lib = MotionLib.from_clips([make_test_clip(num_frames=10)])
    cfg = TrainConfig(env=EnvConfig(groups=(GroupConfig(name="full"),)), player_policies="separate")
    with pytest.raises(ValueError, match="two-player scene"):
        Learner(cfg, env=HumanoidEnv(cfg.env, motion_libs=(lib,), init_lib=lib))
    with pytest.raises(ValueError, match="player_policies must be"):
        _learner("both")
    assert dataclasses.replace(cfg, player_policies="shared").player_policies == "shared"


# ---- the opponent pool (``pool.py``) ---------------------------------------------------------


def _pool_learner(**kw) -> Learner:
    learner = _learner("shared")
    cfg = dataclasses.replace(learner.cfg, **dict(dict(opponent_pool=2, opponent_share=0.25, opponent_every=2), **kw))
    return Learner(cfg, env=Duel(cfg.env))


def test_pool_bouts_have_player_1_acted_by_their_pool_member():
    learner = _pool_learner()
    pool = learner.pool
    assert pool.bouts == 4  # a quarter of 16 bouts
    ts = learner.init(jax.random.PRNGKey(0))
    other = learner.policy.init(jax.random.PRNGKey(7))  # member 1: another policy than member 0
    ps = ts.pool.replace(
        policy_params=jax.tree.map(lambda s, x: s.at[1].set(x), ts.pool.policy_params, other),
        opponent=jnp.array([0, 1, 1, 0], jnp.int32),
    )
    obs = jnp.tile(jnp.linspace(-0.5, 0.5, 16)[:, None, None], (1, 2, 1))
    a, _, _ = learner.act(ts, obs, None)
    mixed = pool.act(learner._act, ps, None, obs, a, None)
    member = [jax.tree.map(lambda x, k=k: x[k], (ps.policy_params, ps.obs_norm)) for k in range(2)]
    for b, k in enumerate([0, 1, 1, 0]):
        sub = ts.replace(policy_params=member[k][0], obs_norm=member[k][1])
        want, _, _ = learner._act(sub, obs[b : b + 1, 1], None)
        np.testing.assert_allclose(mixed[b, 1], want[0], rtol=1e-6, atol=1e-6)
    np.testing.assert_array_equal(mixed[:, 0], a[:, 0])  # the learner's side and the other bouts: the learner
    np.testing.assert_array_equal(mixed[4:], a[4:])
    assert not np.allclose(mixed[1, 1], a[1, 1])


def test_pool_transitions_are_left_out_of_the_update():
    learner = _pool_learner()
    ts = learner.init(jax.random.PRNGKey(0))
    ts, traj = learner.rollout(ts)
    assert traj.obs.shape == (8, 32, 1)
    kept = learner.pool.learner_samples(traj)
    assert kept.obs.shape == (8, 28, 1)  # 16 bouts x 2 players, less player 1 of the 4 pool bouts
    ids = jnp.broadcast_to(jnp.arange(32), (8, 32))
    np.testing.assert_array_equal(learner.pool.learner_samples(ids)[0], [0, 2, 4, 6] + list(range(8, 32)))
    # Changing what the pool's players did changes nothing the learner trains on.
    garbage = traj.replace(task_reward=traj.task_reward.at[:, 1:8:2].set(1e6), action=traj.action.at[:, 1:8:2].set(9.0))
    for a, b in zip(
        jax.tree.leaves(learner.pool.learner_samples(traj)), jax.tree.leaves(learner.pool.learner_samples(garbage))
    ):
        np.testing.assert_array_equal(a, b)
    ts2, m = learner.iteration(learner.init(jax.random.PRNGKey(0)))
    assert all(np.all(np.isfinite(np.asarray(v))) for v in jax.tree.leaves(m))
    assert int(m["pool/filled"]) == 1 and "pool/target" in m


def test_pool_snapshots_fill_a_ring_and_members_are_drawn_among_them():
    learner = _pool_learner()
    pool = learner.pool
    ts = learner.init(jax.random.PRNGKey(0))
    ps = ts.pool
    versions = [jax.tree.map(lambda x, v=v: jnp.full_like(x, v), ts.policy_params) for v in range(1, 6)]
    first = lambda s, k: float(jax.tree.leaves(s.policy_params)[0][k].ravel()[0])
    untrained = first(ps, 0)
    for it, params in enumerate(versions, start=1):  # every 2 iterations into slot 1, 0, 1, ...
        ps = pool.snapshot(ps, params, ts.obs_norm, jnp.asarray(it))
        if it == 1:
            assert int(ps.filled) == 1 and first(ps, 0) == untrained
        if it == 2:
            assert int(ps.filled) == 2 and first(ps, 1) == 2.0 and first(ps, 0) == untrained
    assert int(ps.filled) == 2 and first(ps, 0) == 4.0 and first(ps, 1) == 2.0  # iteration 4 replaced the oldest
    one = ts.pool  # only the untrained policy so far: every draw is member 0
    drawn = pool.redraw(one, jnp.ones((16,), bool), jax.random.PRNGKey(1))
    np.testing.assert_array_equal(drawn.opponent, 0)
    two = ps.replace(opponent=jnp.array([1, 1, 1, 1], jnp.int32))
    draws = [
        pool.redraw(two, jnp.array([True, False, True, False] + [False] * 12), jax.random.PRNGKey(k)).opponent
        for k in range(20)
    ]
    draws = np.stack(draws)
    np.testing.assert_array_equal(draws[:, [1, 3]], 1)  # bouts that go on keep their member
    assert set(draws[:, [0, 2]].ravel()) == {0, 1}


def test_pool_settings_are_checked():
    with pytest.raises(ValueError, match="player_policies=shared"):
        Learner(
            dataclasses.replace(_learner("separate").cfg, opponent_pool=2), env=Duel(EnvConfig(groups=(), players=2))
        )
    with pytest.raises(ValueError, match="pool bouts"):
        _pool_learner(opponent_share=1.0)
    with pytest.raises(ValueError, match="opponent_every"):
        _pool_learner(opponent_every=0)
