"""Tests of jaxmotion.nets.networks: shapes, heads, initialisation, PopArt param path."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxmotion.algos import popart
from jaxmotion.nets import networks

D, A, K = 6, 4, 3
SMALL = (16, 8)


def _obs(n=5, seed=1):
    return jax.random.normal(jax.random.PRNGKey(seed), (n, D))


@pytest.mark.parametrize("state_dependent_std", [True, False])
def test_policy_shapes_and_initial_std(state_dependent_std):
    net = networks.make_policy_network(
        D, A, hidden_sizes=SMALL, state_dependent_std=state_dependent_std, init_log_std=-3.0
    )
    params = net.init(jax.random.PRNGKey(0))
    mean, log_std = net.apply(params, _obs())
    assert mean.shape == (5, A) and log_std.shape == (5, A)
    assert np.isfinite(mean).all() and np.isfinite(log_std).all()
    np.testing.assert_allclose(log_std, -3.0, atol=1e-2)
    # Unbatched input works too.
    mean1, log_std1 = net.apply(params, _obs()[0])
    assert mean1.shape == (A,) and log_std1.shape == (A,)
    if state_dependent_std:
        kernel = params["params"]["log_std"]["kernel"]
        assert kernel.shape == (SMALL[-1], A) and np.abs(kernel).max() <= 1e-4
        np.testing.assert_allclose(params["params"]["log_std"]["bias"], -3.0)
    else:
        np.testing.assert_allclose(params["params"]["log_std"], -3.0)


@pytest.mark.parametrize("activation", sorted(networks.ACTIVATIONS))
def test_activations(activation):
    net = networks.make_critic_network(D, K, hidden_sizes=SMALL, activation=activation)
    values = net.apply(net.init(jax.random.PRNGKey(0)), _obs())
    assert values.shape == (5, K) and np.isfinite(values).all()


def test_unknown_activation_raises():
    net = networks.make_critic_network(D, K, hidden_sizes=SMALL, activation="swishy")
    with pytest.raises(ValueError, match="swishy"):
        net.init(jax.random.PRNGKey(0))


def test_default_sizes():
    # eval_shape: shapes only, no (slow, un-jitted) initialisation of the full-size layers.
    key = jax.random.PRNGKey(0)
    pp = jax.eval_shape(networks.make_policy_network(D, A).init, key)
    cp = jax.eval_shape(networks.make_critic_network(D, K).init, key)
    assert pp["params"]["torso"]["hidden_0"]["kernel"].shape == (D, 1024)
    assert pp["params"]["torso"]["hidden_1"]["kernel"].shape == (1024, 512)
    assert networks.value_head(cp)[0].shape == (512, K)


def test_critic_heads_and_popart_path():
    net = networks.make_critic_network(D, K, hidden_sizes=SMALL)
    params = net.init(jax.random.PRNGKey(0))
    kernel = params["params"]["value_head"]["kernel"]
    bias = params["params"]["value_head"]["bias"]
    assert kernel.shape == (SMALL[-1], K) and bias.shape == (K,)
    assert np.abs(kernel).max() <= 1e-4 and np.all(bias == 0)
    k, b = networks.value_head(params)
    assert k is kernel and b is bias
    values = net.apply(params, _obs())
    assert values.shape == (5, K) and np.isfinite(values).all()


def test_popart_rescale_of_critic_preserves_outputs():
    net = networks.make_critic_network(D, K, hidden_sizes=SMALL)
    params = net.init(jax.random.PRNGKey(0))
    # Give the head non-trivial weights so the check is meaningful.
    k, b = networks.value_head(params)
    params = networks.replace_value_head(params, k * 1e3, b + 0.5)
    obs = _obs(32)
    old = popart.popart_update(popart.popart_init(K), jnp.arange(3.0) + jnp.ones((4, K)))
    new = popart.popart_update(old, jax.random.normal(jax.random.PRNGKey(2), (64, K)) * 7 + 3)
    before = popart.denormalize(old, net.apply(params, obs))
    w, b = popart.preserve_outputs(old, new, *networks.value_head(params))
    params2 = networks.replace_value_head(params, w, b)
    after = popart.denormalize(new, net.apply(params2, obs))
    np.testing.assert_allclose(after, before, rtol=1e-5, atol=1e-5)
    # The torso is untouched and the original params are not modified.
    assert params2["params"]["torso"] is params["params"]["torso"]
    assert networks.value_head(params)[0] is not networks.value_head(params2)[0]


def test_discriminator_heads_and_orthogonal_init():
    net = networks.make_discriminator_network(D, num_heads=32, hidden_sizes=(16, 8))
    params = net.init(jax.random.PRNGKey(0))
    logits = net.apply(params, _obs())
    assert logits.shape == (5, 32) and np.isfinite(logits).all()
    w = params["params"]["torso"]["hidden_0"]["kernel"]  # [D, 16]: orthonormal rows
    np.testing.assert_allclose(w @ w.T, np.eye(D), atol=1e-5)
    heads = params["params"]["heads"]["kernel"]  # [8, 32]
    np.testing.assert_allclose(heads @ heads.T, np.eye(8), atol=1e-5)
    default = jax.eval_shape(networks.make_discriminator_network(D).init, jax.random.PRNGKey(0))
    assert default["params"]["heads"]["kernel"].shape == (128, 32)


def test_authors_init_options_critic_hidden_uniform_and_disc_gain():
    """``NetConfig.critic_hidden_init`` and ``disc_hidden_gain`` (the authors' 1e-4 and sqrt 2)."""
    crit = networks.make_critic_network(D, K, hidden_sizes=SMALL, hidden_init_scale=1e-4)
    p = crit.init(jax.random.PRNGKey(0))["params"]["torso"]
    assert all(float(np.abs(p[f"hidden_{i}"]["kernel"]).max()) <= 1e-4 for i in range(len(SMALL)))
    p0 = networks.make_critic_network(D, K, hidden_sizes=SMALL).init(jax.random.PRNGKey(0))["params"]["torso"]
    assert float(np.abs(p0["hidden_0"]["kernel"]).max()) > 0.1  # PyTorch default U(+-1/sqrt(D))
    disc = networks.make_discriminator_network(D, num_heads=4, hidden_sizes=(16, 8), hidden_gain=np.sqrt(2))
    q = disc.init(jax.random.PRNGKey(0))["params"]
    w = q["torso"]["hidden_0"]["kernel"]
    np.testing.assert_allclose(w @ w.T, 2 * np.eye(D), atol=1e-5)
    h = q["heads"]["kernel"]
    np.testing.assert_allclose(h.T @ h, np.eye(4), atol=1e-5)  # [8, 4]: the heads keep gain 1


def test_policies_share_one_interface_and_the_incremental_one_adds_the_frozen_action():
    """``nets/policies.py``: the learner only calls ``init``, ``extra``, ``dist`` and ``weights``.
    A plain policy conditions on nothing and has no weights; the incremental policy's mean is
    mu + w * a_meta with the meta action outside the gradient, and starts near the meta action."""
    from jaxmotion.nets.policies import GaussianPolicy, IncrementalPolicy

    obs_size, act, batch = 6, 3, 4
    obs = jax.random.normal(jax.random.PRNGKey(0), (batch, obs_size))
    plain = GaussianPolicy(obs_size, act, hidden_sizes=(8,))
    pp = plain.init(jax.random.PRNGKey(1))
    assert plain.extra(None, obs, None).shape == (batch, 0) and plain.weights(pp, obs).shape == (batch, 0)
    mean, log_std = plain.dist(pp, obs, plain.extra(None, obs, None))
    np.testing.assert_allclose(mean, plain.net.apply(pp, obs)[0])

    meta_act = lambda frozen, o, rng: frozen * jnp.ones(o.shape[:-1] + (act,))
    inc = IncrementalPolicy(obs_size, act, meta_act, meta_weight_bias=3.0, hidden_sizes=(8,))
    ip = inc.init(jax.random.PRNGKey(2))
    extra = inc.extra(2.0, obs, None)
    np.testing.assert_allclose(extra, 2.0)
    mean, _ = inc.dist(ip, obs, extra)
    mu, _, w = inc.net.apply(ip, obs)
    np.testing.assert_allclose(mean, mu + w * extra, rtol=1e-6)
    np.testing.assert_allclose(inc.weights(ip, obs), w)
    np.testing.assert_allclose(mean, 2.0 / (1.0 + np.exp(-3.0)), atol=1e-2)  # starts as 0.95 x the meta action
    g = jax.grad(lambda e: inc.dist(ip, obs, e)[0].sum())(extra)
    np.testing.assert_array_equal(g, 0.0)
