"""The mixture-of-experts policy (Won et al. 2021): its gate and smoothing by hand, the carried
gate state in the rollout, the transfer of its decoder and the encoder-only/end-to-end schedule.

The learner-level tests share one tiny configuration and one compiled iteration; the run-level
test trains two chunks (stopped after one and resumed) and transfers the run's decoder."""

from __future__ import annotations

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from conftest import jit_enabled
from jaxmotion import config as C
from jaxmotion.config.checks import validate
from jaxmotion.config.errors import ConfigError
from jaxmotion.nets.moe import DECODER, MoEPolicy, decoder_learns
from jaxmotion.training import run as run_mod
from jaxmotion.training.learner import Learner
from jaxmotion.training import runs as runs_mod
from jaxmotion.training.runs import InitFromError, transfer_decoder

OBS, BODY, ACT, N = 12, 7, 3, 4


def _policy(alpha: float) -> tuple[MoEPolicy, dict]:
    pol = MoEPolicy(OBS, ACT, BODY, num_experts=N, alpha=alpha, expert_hidden=(8,), encoder_hidden=(8,))
    params = pol.init(jax.random.PRNGKey(0))
    # A gate far from its near-zero start, so the tests see it act.
    params["params"]["gate"]["kernel"] = jax.random.normal(
        jax.random.PRNGKey(1), params["params"]["gate"]["kernel"].shape
    )
    return pol, params


def _obs(key: int, shape=(5,)) -> jax.Array:
    return jax.random.normal(jax.random.PRNGKey(key), shape + (OBS,))


def test_alpha_zero_is_memoryless_gating():
    pol, params = _policy(0.0)
    x = _obs(2)
    prev = jax.random.uniform(jax.random.PRNGKey(3), (5, N), minval=-1, maxval=1)
    m0, s0 = pol.dist(params, x, jnp.zeros((5, N)))
    m1, s1 = pol.dist(params, x, prev)
    np.testing.assert_array_equal(m0, m1)
    np.testing.assert_array_equal(s0, s1)
    np.testing.assert_allclose(pol.next_carry(params, x, prev), pol.weights(params, x), atol=0)


def test_smoothed_gate_and_mixture_by_hand():
    alpha = 0.9
    pol, params = _policy(alpha)
    x = _obs(4)
    prev = jax.random.uniform(jax.random.PRNGKey(5), (5, N), minval=-1, maxval=1)
    omega, experts = np.asarray(pol.weights(params, x)), np.asarray(pol.experts(params, x))
    assert np.all(np.abs(omega) < 1)  # tanh: in (-1, 1), not normalised
    hat = (1 - alpha) * omega + alpha * np.asarray(prev)
    mean, _ = pol.dist(params, x, prev)
    np.testing.assert_allclose(mean, np.einsum("bn,bna->ba", hat, experts), rtol=1e-5, atol=1e-6)
    np.testing.assert_allclose(pol.next_carry(params, x, prev), hat, rtol=1e-6, atol=1e-7)


def test_experts_read_only_the_body_state_and_the_gate_reads_everything():
    pol, params = _policy(0.9)
    x = _obs(6)
    y = x.at[:, BODY:].set(_obs(7)[:, BODY:])  # other task features, the same body state
    np.testing.assert_array_equal(pol.experts(params, x), pol.experts(params, y))
    assert not np.allclose(pol.weights(params, x), pol.weights(params, y))


def test_the_gate_starts_near_zero_and_the_decoder_mask_names_experts_and_sigma():
    pol = MoEPolicy(OBS, ACT, BODY, num_experts=N)
    params = pol.init(jax.random.PRNGKey(0))
    assert float(jnp.abs(pol.weights(params, _obs(8))).max()) < 0.05
    mask = pol.decoder_mask(params)["params"]
    for name, sub in mask.items():
        assert all(jax.tree.leaves(sub)) == (name in DECODER) and len(set(jax.tree.leaves(sub))) == 1


def test_the_lstm_encoder_carries_its_memory_with_the_gate():
    pol = MoEPolicy(OBS, ACT, BODY, num_experts=N, alpha=0.0, expert_hidden=(8,), encoder_hidden=(6, 8), encoder="lstm")
    params = pol.init(jax.random.PRNGKey(0))
    params["params"]["gate"]["kernel"] = jax.random.normal(
        jax.random.PRNGKey(1), params["params"]["gate"]["kernel"].shape
    )
    assert pol.carry_size == N + 2 * 6 and pol.weight_size == 0
    x1, x2 = _obs(10), _obs(11)
    c0 = jnp.zeros((5, pol.carry_size))
    c1 = pol.next_carry(params, x1, c0)
    assert np.abs(np.asarray(c1[:, N:])).max() > 0  # the LSTM state moved
    # The same observation acts differently after another history (alpha 0: through the memory
    # alone), and the stored carry reproduces the acting distribution exactly.
    assert not np.allclose(pol.dist(params, x2, c1)[0], pol.dist(params, x2, c0)[0])
    np.testing.assert_array_equal(pol.dist(params, x2, c1)[0], pol.dist(params, x2, jnp.array(c1))[0])
    np.testing.assert_array_equal(pol.experts(params, x2), pol.experts(params, x2.at[:, BODY:].set(0.0)))


def test_decoder_schedule_by_hand():
    learns = [bool(decoder_learns(jnp.int32(i), 3, 2)) for i in range(10)]
    assert learns == [False, False, False, True, True, False, False, True, True, False]
    assert [bool(decoder_learns(jnp.int32(i), 2, 0)) for i in range(5)] == [False, False, True, True, True]
    assert all(bool(decoder_learns(jnp.int32(i), 0, 0)) for i in range(3))


NET = dict(
    policy="moe",
    experts=3,
    gate_alpha=0.8,
    expert_hidden=(8,),
    encoder_hidden=(8,),
    critic_hidden=(16, 16),
    disc_hidden=(16, 16),
    disc_heads=2,
)


def tiny_moe(net: dict | None = None, **kw):
    """The smoke experiment with a small mixture of experts: 4 envs x horizon 4, 3-step episodes
    (so the rollout crosses episode ends); ``net`` overrides network settings."""
    base = C.load_experiment("smoke")
    return dataclasses.replace(
        base,
        env=dataclasses.replace(base.env, episode_steps=3),
        net=dataclasses.replace(base.net, **{**NET, **(net or {})}),
        ppo=dataclasses.replace(base.ppo, num_envs=4, horizon=4, minibatch_size=8, epochs=1, actor_lr=1e-3),
        disc=dataclasses.replace(base.disc, minibatch_size=8),
        iterations=2,
        chunk=1,
        checkpoint_every=1,
        **kw,
    )


@pytest.fixture(scope="module")
def moe_learner(data_dir):
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("JAXMOTION_DATA", str(data_dir))
        learner = Learner(tiny_moe(decoder_start=1, decoder_every=1))
        with jit_enabled():
            ts = learner.init(jax.random.PRNGKey(0))
            yield learner, ts, jax.jit(learner.iteration), jax.jit(learner.rollout)


def _decoder(ts):
    return {k: np.asarray(jax.tree.leaves(ts.policy_params["params"][k])[0]) for k in ("experts", "encoder")}


def test_gate_state_rides_in_the_rollout_and_resets_at_episode_ends(moe_learner):
    learner, ts, _, rollout = moe_learner
    with jit_enabled():
        _, traj = rollout(ts)
    carry = np.asarray(traj.extra)  # [T, B, N]: the gate state each step acted with
    done = np.asarray(traj.terminated | traj.truncated)
    assert carry.shape == (4, 4, 3) and done[:-1].any()  # episodes of 3 steps end within 4
    np.testing.assert_array_equal(carry[0], 0.0)  # every environment starts an episode
    nobs = learner.normalize_obs(ts.obs_norm, traj.obs)
    nxt = np.asarray(learner.policy.next_carry(ts.policy_params, nobs, traj.extra))
    expect = np.where(done[:-1, :, None], 0.0, nxt[:-1])
    np.testing.assert_allclose(carry[1:], expect, rtol=1e-5, atol=1e-7)
    assert np.abs(carry[1:][~done[:-1]]).max() > 0


def test_encoder_only_turns_leave_the_decoder_bit_identical(moe_learner):
    learner, ts, iteration, _ = moe_learner
    with jit_enabled():
        t1, m = iteration(ts)  # iteration 0: encoder only
        t2, _ = iteration(t1)  # iteration 1: end to end
        t3, _ = iteration(t2)  # iteration 2: encoder only again
    assert all(np.isfinite(np.asarray(v)).all() for v in jax.tree.leaves(m))
    d0, d1, d2, d3 = (_decoder(t) for t in (ts, t1, t2, t3))
    np.testing.assert_array_equal(d1["experts"], d0["experts"])
    assert not np.array_equal(d1["encoder"], d0["encoder"])
    assert not np.array_equal(d2["experts"], d1["experts"])
    np.testing.assert_array_equal(d3["experts"], d2["experts"])
    assert not np.array_equal(d3["encoder"], d2["encoder"])


def test_moe_settings_are_checked(data_dir):
    with pytest.raises(ConfigError, match="decoder_start"):
        validate(dataclasses.replace(C.load_experiment("smoke"), decoder_start=5))
    with pytest.raises(ConfigError, match="net.policy"):
        validate(tiny_moe(meta="runs/x"))


def test_a_resumed_run_keeps_its_turn_and_a_sport_takes_its_decoder(data_dir, tmp_path):
    """Pretraining stand-in: two iterations, the decoder frozen in the first; stopped after one
    and resumed, the second (end to end) moves the decoder, so the turn came from the iteration
    count. Then a new run takes the decoder and body statistics, and keeps its own encoder.

    One learner and one compiled chunk serve every run here (``make_learner`` and
    ``make_train_chunk`` memoised), as separate processes would build equal ones."""
    cfg = tiny_moe(decoder_start=1)
    learners, chunks = {}, {}
    real_learner, real_chunk = runs_mod.make_learner, run_mod.make_train_chunk

    def learner_for(c, env=None):
        key = dataclasses.replace(c, resume="")
        if key not in learners:
            learners[key] = real_learner(c, env)
        return learners[key]

    def chunk_for(learner, mesh, chunk, example):
        if (id(learner), chunk) not in chunks:
            chunks[(id(learner), chunk)] = real_chunk(learner, mesh, chunk, example)
        return chunks[(id(learner), chunk)]

    with pytest.MonkeyPatch.context() as mp, jit_enabled():
        mp.setenv("JAXMOTION_DATA", str(data_dir))
        mp.setattr(run_mod, "make_learner", learner_for)
        mp.setattr(runs_mod, "make_learner", learner_for)
        mp.setattr(run_mod, "make_train_chunk", chunk_for)
        src = tmp_path / "src"
        first = run_mod.train("smoke", cfg, run_dir=src, progress=False, tensorboard=False, stop_after_chunks=1)
        learner = learner_for(cfg)
        init = learner.init(jax.random.PRNGKey(cfg.seed))
        np.testing.assert_array_equal(_decoder(first.state)["experts"], _decoder(init)["experts"])
        done = run_mod.train("smoke", dataclasses.replace(cfg, resume=str(src)), progress=False, tensorboard=False)
        assert int(done.state.iteration) == 2 and len(chunks) == 1
        assert not np.array_equal(_decoder(done.state)["experts"], _decoder(first.state)["experts"])

        fresh = learner.init(jax.random.PRNGKey(7))  # another run's new networks
        moved = transfer_decoder(learner, fresh, src)
        params = lambda ts, k: jax.tree.leaves(ts.policy_params["params"][k])
        for k in DECODER:
            for a, b in zip(params(moved, k), params(done.state, k)):
                np.testing.assert_array_equal(a, b)
        for a, b in zip(
            params(moved, "encoder") + params(moved, "gate"), params(fresh, "encoder") + params(fresh, "gate")
        ):
            np.testing.assert_array_equal(a, b)
        np.testing.assert_array_equal(moved.obs_norm.mean, done.state.obs_norm.mean)

        other = Learner(tiny_moe(net=dict(experts=2)))
        shapes = jax.eval_shape(other.init, jax.random.PRNGKey(0))  # the check needs only shapes
        with pytest.raises(InitFromError, match="do not fit"):
            transfer_decoder(other, shapes, src)
        with pytest.raises(InitFromError, match="decoder_from="):
            transfer_decoder(other, shapes, tmp_path / "nothing")
