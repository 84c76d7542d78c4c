"""The composer of frozen primitives (``nets/composer.py``, ``training/primitives.py``): the
composition rules against hand computation, the composite log-probability against the product
of the weighted densities, and a training chunk that trains the composer and leaves every
primitive bit for bit as it was."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from conftest import jit_enabled
from jaxmotion import config as C
from jaxmotion.algos import ppo as PPO
from jaxmotion.nets.composer import compose
from jaxmotion.training.learner import Learner
from jaxmotion.training.loop import make_mesh, make_train_chunk, shard_state
from jaxmotion.training.primitives import Primitives, PrimitivesError
from jaxmotion.training.runs import make_learner
from test_train import _leaves, motion_data, tiny_config  # noqa: F401

K, A = 3, 5


def _gaussians(seed: int = 0, batch: int = 4):
    rng = np.random.default_rng(seed)
    means = rng.normal(size=(batch, K, A)).astype(np.float32)
    log_stds = rng.uniform(-3.0, 0.0, size=(batch, K, A)).astype(np.float32)
    return means, log_stds


@pytest.mark.parametrize("rule", ["product", "sum"])
def test_one_hot_weights_give_that_primitive_exactly(rule):
    means, log_stds = _gaussians()
    own = jnp.full((A,), -2.9)
    for i in range(K):
        w = jnp.zeros((4, K)).at[:, i].set(1.0)
        mean, log_std = compose(rule, w, means, log_stds, own)
        np.testing.assert_array_equal(mean, means[:, i])
        if rule == "product":
            np.testing.assert_allclose(log_std, log_stds[:, i], rtol=0, atol=1e-6)
        else:
            np.testing.assert_array_equal(log_std, np.broadcast_to(own, (4, A)))


def test_with_equal_sigmas_the_product_is_the_weighted_mean_of_the_means():
    means, _ = _gaussians(1)
    log_stds = np.full_like(means, -1.3)
    w = np.random.default_rng(2).uniform(0.05, 1.0, size=(4, K)).astype(np.float32)
    mean, log_std = compose("product", jnp.asarray(w), means, log_stds)
    expect = (w[..., None] * means).sum(1) / w.sum(1, keepdims=True)
    np.testing.assert_allclose(mean, expect, rtol=1e-5, atol=1e-6)
    # sigma^2 = sigma_0^2 / sum(w)
    np.testing.assert_allclose(log_std, -1.3 - 0.5 * np.log(w.sum(1, keepdims=True)) + 0 * expect, rtol=1e-5)


def test_sum_rule_is_the_unnormalised_weighted_sum_of_the_means():
    means, log_stds = _gaussians(3)
    w = np.array([[0.2, 0.5, 1.5]] * 4, np.float32)
    mean, log_std = compose("sum", jnp.asarray(w), means, log_stds, jnp.full((A,), -2.9))
    np.testing.assert_allclose(mean, (w[..., None] * means).sum(1), rtol=1e-6)
    np.testing.assert_array_equal(log_std, np.full((4, A), -2.9, np.float32))


def test_product_log_probability_matches_the_closed_form():
    """log N(a; mu_c, sigma_c) against (i) the closed form in float64 and (ii) the product of the
    weighted densities, prod_i N(a; mu_i, sigma_i)^w_i, which is the composite up to a constant:
    their differences between two actions agree."""
    means, log_stds = _gaussians(4, batch=1)
    w = np.array([[0.3, 0.9, 0.6]], np.float32)
    mean, log_std = compose("product", jnp.asarray(w), means, log_stds)
    m, s = means[0].astype(np.float64), np.exp(log_stds[0].astype(np.float64))
    prec = w[0, :, None] * s**-2
    var_c = 1 / prec.sum(0)
    mu_c = var_c * (prec * m).sum(0)
    rng = np.random.default_rng(5)
    acts = rng.normal(size=(2, A))
    closed = [np.sum(-0.5 * (a - mu_c) ** 2 / var_c - 0.5 * np.log(2 * np.pi * var_c)) for a in acts]
    ours = [float(PPO.gaussian_log_prob(mean[0], log_std[0], jnp.asarray(a, jnp.float32))) for a in acts]
    np.testing.assert_allclose(ours, closed, rtol=1e-5, atol=1e-4)

    def weighted_product(a):
        return np.sum(w[0, :, None] * (-0.5 * (a - m) ** 2 / s**2 - np.log(s) - 0.5 * np.log(2 * np.pi)))

    np.testing.assert_allclose(
        ours[0] - ours[1], weighted_product(acts[0]) - weighted_product(acts[1]), rtol=1e-4, atol=1e-4
    )


def test_unknown_rule_and_conflicting_settings_are_one_line():
    with pytest.raises(ValueError, match="unknown composition rule"):
        compose("mean", jnp.ones((1, K)), *_gaussians())
    cfg = tiny_config()
    with pytest.raises(C.ConfigError, match="net.composer"):
        C.apply_overrides(cfg, ["net.composer=mean"])
    bad = dataclasses.replace(cfg, primitives=("a",), meta="b")
    with pytest.raises(C.ConfigError, match="primitives"):
        make_learner(bad)


@pytest.fixture(scope="module")
def composer(motion_data):  # noqa: F811
    """Two untrained primitives of the tiny config (different seeds) and a product composer."""
    cfg = tiny_config()
    with jit_enabled():
        base = make_learner(cfg)
        loaded = [(Path(f"p{i}"), base, base.init(jax.random.PRNGKey(10 + i))) for i in range(2)]
        prims = Primitives(loaded, base.env)
        learner = Learner(dataclasses.replace(cfg, primitives=("p0", "p1")), base.env, meta=prims)
        ts = learner.init(jax.random.PRNGKey(0))
    return dict(base=base, loaded=loaded, prims=prims, learner=learner, ts=ts)


@pytest.mark.slow
def test_the_composer_acts_as_the_product_of_its_primitives(composer):
    learner, ts, base, loaded = composer["learner"], composer["ts"], composer["base"], composer["loaded"]
    obs = ts.obs
    with jit_enabled():
        mean, _, extra = learner.act(ts, obs, None)
        w = np.asarray(learner.policy_weights(ts, obs), np.float64)
        own = [base.act(lts, obs, None)[0] for _, _, lts in loaded]  # each primitive alone
        dists = [
            base.policy.dist(lts.policy_params, base.normalize_obs(lts.obs_norm, obs), extra[..., :0])
            for _, _, lts in loaded
        ]
    assert w.shape == (obs.shape[0], 2) and np.all(np.abs(w - 0.5) < 0.01)  # sigmoid starts at 0.5
    for i in range(2):  # what the composer stored is each primitive's own Gaussian
        np.testing.assert_allclose(np.asarray(dists[i][0]), np.asarray(own[i]), rtol=1e-6, atol=1e-6)
    m = np.stack([np.asarray(d[0], np.float64) for d in dists], 1)
    prec = w[..., None] * np.exp(-2 * np.stack([np.asarray(d[1], np.float64) for d in dists], 1))
    np.testing.assert_allclose(np.asarray(mean), (prec * m).sum(1) / prec.sum(1), rtol=1e-4, atol=1e-5)


@pytest.mark.slow
def test_a_training_chunk_trains_the_composer_and_leaves_the_primitives_bit_identical(composer):
    learner, ts = composer["learner"], composer["ts"]
    before_meta, before_pol = _leaves(ts.meta), _leaves(ts.policy_params)
    with jit_enabled():
        mesh = make_mesh()
        state = shard_state(ts, mesh)
        chunk = make_train_chunk(learner, mesh, 1, state)
        after, metrics = chunk(state)
    after_meta = dict(_leaves(after.meta))
    for k, x in before_meta:
        np.testing.assert_array_equal(after_meta[k], x, err_msg=k)
    changed = [k for k, x in _leaves(after.policy_params) if not np.array_equal(x, dict(before_pol)[k])]
    assert "['params']['weights']['kernel']" in changed, changed
    assert all(np.isfinite(np.asarray(v)).all() for v in jax.tree.leaves(metrics))


def test_primitives_of_another_task_layout_are_refused(composer):
    base, loaded = composer["base"], composer["loaded"]

    class Other:
        action_size, obs_size = base.env.action_size, base.env.obs_size + 1

    with pytest.raises(PrimitivesError, match="observations"):
        Primitives(loaded, Other())
    with pytest.raises(PrimitivesError, match="at least one"):
        Primitives([], base.env)
