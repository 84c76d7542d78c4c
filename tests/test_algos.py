"""Tests of jaxmotion.algos: GAE, PopArt, PPO losses, discriminator loss/reward, normaliser."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

from jaxmotion.algos import disc, gae, normalizer, popart, ppo
from jaxmotion.nets import networks

# --------------------------------------------------------------------------------------------
# GAE


def _gae_reference(rewards, values, next_values, term, trunc, gamma, lam):
    """Plain Python loop over time, one objective at a time."""
    T = rewards.shape[0]
    adv = np.zeros_like(rewards)
    last = np.zeros_like(rewards[0])
    for t in reversed(range(T)):
        term_t = term[t][..., None]
        done_t = np.maximum(term[t], trunc[t])[..., None]
        delta = rewards[t] + gamma * (1 - term_t) * next_values[t] - values[t]
        last = delta + gamma * lam * (1 - done_t) * last
        adv[t] = last
    return adv, adv + values


def _gae_data(seed=0, T=9, B=5, K=3):
    rng = np.random.default_rng(seed)
    rewards = rng.normal(size=(T, B, K)).astype(np.float32)
    values = rng.normal(size=(T, B, K)).astype(np.float32)
    next_values = rng.normal(size=(T, B, K)).astype(np.float32)
    term = (rng.random((T, B)) < 0.2).astype(np.float32)
    trunc = (rng.random((T, B)) < 0.2).astype(np.float32)
    trunc[2, 0], term[2, 0] = 1.0, 1.0  # both set: termination wins
    return rewards, values, next_values, term, trunc


def test_gae_matches_python_loop():
    rewards, values, next_values, term, trunc = _gae_data()
    assert term.sum() > 0 and trunc.sum() > 0
    adv, ret = gae.compute_gae(rewards, values, next_values, term, trunc, gamma=0.95, lam=0.9)
    ref_adv, ref_ret = _gae_reference(rewards, values, next_values, term, trunc, 0.95, 0.9)
    assert adv.shape == rewards.shape and ret.shape == rewards.shape
    np.testing.assert_allclose(adv, ref_adv, rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(ret, ref_ret, rtol=1e-5, atol=1e-5)


def test_gae_episode_end_semantics():
    rewards, values, next_values, term, trunc = _gae_data(seed=1)
    term[:] = 0.0
    trunc[:] = 0.0
    term[3, 1] = 1.0
    trunc[5, 2] = 1.0
    adv, _ = gae.compute_gae(rewards, values, next_values, term, trunc, gamma=0.9, lam=0.8)
    np.testing.assert_allclose(adv[3, 1], rewards[3, 1] - values[3, 1], rtol=1e-6)
    np.testing.assert_allclose(adv[5, 2], rewards[5, 2] + 0.9 * next_values[5, 2] - values[5, 2], rtol=1e-6)
    # Last step: plain one-step TD error with bootstrap.
    np.testing.assert_allclose(adv[-1], rewards[-1] + 0.9 * next_values[-1] - values[-1], rtol=1e-6, atol=1e-6)


def test_gae_bootstrap_value_form_and_single_objective():
    rewards, values, _, term, _ = _gae_data(seed=2)
    bootstrap = np.random.default_rng(3).normal(size=values.shape[1:]).astype(np.float32)
    next_values = np.concatenate([values[1:], bootstrap[None]], axis=0)
    adv, ret = gae.compute_gae(rewards, values, bootstrap, term, None, 0.95, 0.95)
    ref_adv, _ = _gae_reference(rewards, values, next_values, term, np.zeros_like(term), 0.95, 0.95)
    np.testing.assert_allclose(adv, ref_adv, rtol=1e-5, atol=1e-5)
    # K-less [T, B] input equals objective 0 of the [T, B, K] computation.
    adv0, _ = gae.compute_gae(rewards[..., 0], values[..., 0], bootstrap[..., 0], term)
    np.testing.assert_allclose(adv0, adv[..., 0], rtol=1e-5, atol=1e-5)


# --------------------------------------------------------------------------------------------
# PopArt


def test_popart_init_is_identity_and_first_update_matches_batch():
    state = popart.popart_init(3)
    x = jnp.arange(6.0).reshape(2, 3)
    np.testing.assert_allclose(popart.normalize(state, x), x)
    np.testing.assert_allclose(popart.denormalize(state, x), x)
    targets = np.random.default_rng(0).normal(5.0, 3.0, size=(64, 3)).astype(np.float32)
    state = popart.popart_update(state, targets, beta=0.1)
    np.testing.assert_allclose(state.mean, targets.mean(0), rtol=1e-5)
    np.testing.assert_allclose(popart.std(state), targets.std(0), rtol=1e-4)
    assert int(state.count) == 1


def test_popart_ema_with_bias_correction():
    rng = np.random.default_rng(1)
    beta, state = 0.3, popart.popart_init(2)
    batches = [rng.normal(i, 1.0 + i, size=(16, 2)).astype(np.float32) for i in range(4)]
    for batch in batches:
        state = popart.popart_update(state, batch, beta)
    m1 = np.stack([b.mean(0) for b in batches])
    w = beta * (1 - beta) ** np.arange(len(batches))[::-1]
    np.testing.assert_allclose(state.mean, (w[:, None] * m1).sum(0) / w.sum(), rtol=1e-5)
    np.testing.assert_allclose(state.debias, 1 - (1 - beta) ** len(batches), rtol=1e-6)


def test_popart_std_floor():
    state = popart.popart_update(popart.popart_init(2), jnp.full((8, 2), 7.0))
    np.testing.assert_allclose(popart.std(state), popart.STD_MIN)


def test_popart_preserves_outputs():
    rng = np.random.default_rng(2)
    H, K = 16, 3
    h = jnp.asarray(rng.normal(size=(32, H)), jnp.float32)
    w = jnp.asarray(rng.normal(size=(H, K)) * 0.1, jnp.float32)
    b = jnp.asarray(rng.normal(size=(K,)), jnp.float32)
    state = popart.popart_init(K)
    for i, (loc, scale) in enumerate([(5.0, 2.0), (-3.0, 10.0), (20.0, 0.5), (0.0, 1.0)]):
        targets = rng.normal(loc, scale, size=(128, K)).astype(np.float32)
        before = popart.denormalize(state, h @ w + b)
        new_state = popart.popart_update(state, targets, beta=0.5)
        assert not np.allclose(new_state.mean, state.mean)  # the statistics move
        w, b = popart.preserve_outputs(state, new_state, w, b)
        state = new_state
        after = popart.denormalize(state, h @ w + b)
        np.testing.assert_allclose(after, before, rtol=1e-5, atol=1e-5, err_msg=f"update {i}")


# --------------------------------------------------------------------------------------------
# PPO


def test_gaussian_log_prob_and_entropy():
    rng = np.random.default_rng(0)
    mean, log_std, x = (rng.normal(size=(4, 3)).astype(np.float32) for _ in range(3))
    sd = np.exp(log_std)
    ref = np.sum(-0.5 * ((x - mean) / sd) ** 2 - np.log(sd) - 0.5 * np.log(2 * np.pi), -1)
    np.testing.assert_allclose(ppo.gaussian_log_prob(mean, log_std, x), ref, rtol=1e-5)
    ref_ent = np.sum(0.5 * np.log(2 * np.pi * np.e * sd**2), -1)
    np.testing.assert_allclose(ppo.gaussian_entropy(log_std), ref_ent, rtol=1e-5)


def test_combine_advantages_formula():
    adv = np.random.default_rng(1).normal(3.0, 2.0, size=(50, 3)).astype(np.float32)
    weights = np.array([0.2, 0.3, 0.5], np.float32)
    combined, standardized = ppo.combine_advantages(adv, weights)
    ref_std = (adv - adv.mean(0)) / (adv.std(0, ddof=1) + 1e-8)
    np.testing.assert_allclose(standardized, ref_std, rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(combined, ref_std @ weights, rtol=1e-5, atol=1e-5)
    raw, _ = ppo.combine_advantages(adv, weights, standardize=False)
    np.testing.assert_allclose(raw, adv @ weights, rtol=1e-6)


def test_clipped_surrogate_hand_computed():
    ratio = jnp.array([1.5, 0.5])
    adv = jnp.array([[2.0, -1.0], [-2.0, 4.0]])
    weights = jnp.array([0.5, 0.5])
    # Eq. 9: combined A = [0.5, 1.0]; min(1.5*.5, 1.2*.5) = .6, min(.5*1, .8*1) = .5.
    eq9 = ppo.clipped_surrogate(jnp.log(ratio), adv, weights, 0.2, per_objective_clip=False)
    np.testing.assert_allclose(eq9, -(0.6 + 0.5) / 2, rtol=1e-6)
    # Per objective: wA = [[1, -.5], [-1, 2]] -> (1.2 - .75) + (-.8 + 1.0) = .45 + .2.
    per = ppo.clipped_surrogate(jnp.log(ratio), adv, weights, 0.2, per_objective_clip=True)
    np.testing.assert_allclose(per, -(0.45 + 0.2) / 2, rtol=1e-6)
    # K = 1: both variants agree.
    one = [ppo.clipped_surrogate(jnp.log(ratio), adv[:, :1], jnp.ones(1), 0.2, c) for c in (0, 1)]
    np.testing.assert_allclose(one[0], one[1])


def _ppo_setup(K, seed=0, N=5, D=6, A=4, std_mode=True):
    # Sizes as in tests/test_nets.py: un-jitted ops are compiled per shape, so sharing saves time.
    policy = networks.make_policy_network(D, A, hidden_sizes=(16, 8), state_dependent_std=std_mode)
    critic = networks.make_critic_network(D, K, hidden_sizes=(16, 8))
    k1, k2, k3, k4 = jax.random.split(jax.random.PRNGKey(seed), 4)
    pp, cp = policy.init(k1), critic.init(k2)
    obs = jax.random.normal(k3, (N, D))
    mean, log_std = policy.apply(pp, obs)
    actions = mean + jnp.exp(log_std) * jax.random.normal(k4, mean.shape)
    log_probs = ppo.gaussian_log_prob(mean, log_std, actions)
    returns = jax.random.normal(k4, (N, K)) * 3.0 + 2.0
    batch = ppo.PPOBatch(obs, actions, log_probs, jnp.zeros((N, K)), returns)
    return policy, critic, pp, cp, batch


@pytest.mark.parametrize("per_objective_clip", [False, True])
def test_ppo_policy_gradient_zero_at_old_policy_with_zero_advantage(per_objective_clip):
    policy, critic, pp, cp, batch = _ppo_setup(K=3)
    grads, _ = jax.grad(ppo.ppo_losses, has_aux=True)(
        pp,
        cp,
        batch,
        policy.apply,
        critic.apply,
        jnp.full(3, 1 / 3),
        per_objective_clip=per_objective_clip,
    )
    for g in jax.tree.leaves(grads):
        np.testing.assert_allclose(g, 0.0, atol=1e-12)


@pytest.mark.parametrize("std_mode", [False, True])
def test_ppo_gradient_at_old_policy_is_vanilla_policy_gradient(std_mode):
    policy, critic, pp, cp, batch = _ppo_setup(K=1, std_mode=std_mode)
    adv = jax.random.normal(jax.random.PRNGKey(5), batch.advantages.shape)
    batch = batch.replace(advantages=adv)
    grads, _ = jax.grad(ppo.ppo_losses, has_aux=True)(pp, cp, batch, policy.apply, critic.apply, jnp.ones(1))

    def pg_loss(params):
        mean, log_std = policy.apply(params, batch.obs)
        return -jnp.mean(adv[:, 0] * ppo.gaussian_log_prob(mean, log_std, batch.actions))

    expected = jax.grad(pg_loss)(pp)
    for got, want in zip(jax.tree.leaves(grads), jax.tree.leaves(expected)):
        np.testing.assert_allclose(got, want, rtol=1e-4, atol=1e-7)


def test_ppo_losses_value_loss_and_metrics():
    K = 2
    policy, critic, pp, cp, batch = _ppo_setup(K=K)
    state = popart.popart_update(popart.popart_init(K), batch.returns)
    loss, metrics = ppo.ppo_losses(pp, cp, batch, policy.apply, critic.apply, jnp.full(K, 0.5), popart_state=state)
    values = critic.apply(cp, batch.obs)
    expected_v = np.mean((values - popart.normalize(state, batch.returns)) ** 2)
    np.testing.assert_allclose(metrics["value_loss"], expected_v, rtol=1e-5)
    np.testing.assert_allclose(loss, 0.5 * expected_v, rtol=1e-5, atol=1e-7)  # zero advantages
    np.testing.assert_allclose(metrics["approx_kl"], 0.0, atol=1e-6)
    np.testing.assert_allclose(metrics["ratio_mean"], 1.0, atol=1e-6)
    assert all(jnp.shape(v) == () for v in metrics.values())
    # Entropy bonus enters with a minus sign.
    loss_ent, m = ppo.ppo_losses(pp, cp, batch, policy.apply, critic.apply, jnp.full(K, 0.5), state, entropy_coef=0.1)
    np.testing.assert_allclose(loss_ent, loss - 0.1 * m["entropy"], rtol=1e-5)


# --------------------------------------------------------------------------------------------
# Discriminator


def _linear_disc(H=3, D=4, seed=0):
    rng = np.random.default_rng(seed)
    params = {
        "W": jnp.asarray(rng.normal(size=(H, D)), jnp.float32),
        "b": jnp.asarray(rng.normal(size=(H,)), jnp.float32),
    }
    return (lambda p, x: x @ p["W"].T + p["b"]), params


@pytest.mark.parametrize("gp_mode", ["per_head", "sum_heads"])
def test_disc_loss_linear_hand_computed(gp_mode):
    apply_fn, params = _linear_disc()
    rng = np.random.default_rng(1)
    pol = rng.normal(size=(6, 4)).astype(np.float32)
    ref = rng.normal(size=(6, 4)).astype(np.float32)
    W, b = np.asarray(params["W"]), np.asarray(params["b"])
    d_pol, d_ref = pol @ W.T + b, ref @ W.T + b
    hinge = np.mean(np.maximum(0, 1 + d_pol)) + np.mean(np.maximum(0, 1 - d_ref))
    gp = np.mean((np.linalg.norm(W, axis=1) - 1) ** 2) if gp_mode == "per_head" else (np.linalg.norm(W.sum(0)) - 1) ** 2
    loss, metrics = disc.disc_loss(apply_fn, params, pol, ref, jax.random.PRNGKey(0), gp_weight=10.0, gp_mode=gp_mode)
    np.testing.assert_allclose(metrics["hinge_loss"], hinge, rtol=1e-5)
    np.testing.assert_allclose(metrics["gradient_penalty"], gp, rtol=1e-5)
    np.testing.assert_allclose(loss, hinge + 10.0 * gp, rtol=1e-5)


def test_disc_per_head_gradients_match_jacobian_on_mlp():
    # Same sizes as tests/test_nets.py, so the un-jitted initialisation is compiled once.
    net = networks.make_discriminator_network(6, num_heads=32, hidden_sizes=(16, 8))
    params = net.init(jax.random.PRNGKey(0))
    x = jax.random.normal(jax.random.PRNGKey(1), (5, 6))
    grads = disc.input_gradients(net.apply, params, x, "per_head")  # [H, N, D]
    jac = jax.vmap(jax.jacrev(lambda xi: net.apply(params, xi)))(x)  # [N, H, D]
    np.testing.assert_allclose(grads, jnp.transpose(jac, (1, 0, 2)), rtol=1e-5, atol=1e-6)
    summed = disc.input_gradients(net.apply, params, x, "sum_heads")
    np.testing.assert_allclose(summed, jac.sum(1), rtol=1e-5, atol=1e-6)
    # Double backward through the penalty is finite.
    loss_fn = lambda p: disc.disc_loss(net.apply, p, x, -x, jax.random.PRNGKey(2))[0]  # noqa: E731
    loss_grads = jax.grad(loss_fn)(params)
    assert all(np.isfinite(g).all() for g in jax.tree.leaves(loss_grads))


@pytest.mark.parametrize(
    "obs_size,hidden,activation",
    [
        (9, (5,), "tanh"),  # D > H_1 (the quadratic form), one layer, act' with a gradient
        (6, (8, 4), "elu"),  # D <= H_1 (the direct product)
        (7, (6, 5, 4), "relu"),  # three hidden layers, D > H_1
    ],
)
def test_structured_head_grad_norms_match_backward_passes(obs_size, hidden, activation):
    net = networks.make_discriminator_network(obs_size, num_heads=3, hidden_sizes=hidden, activation=activation)
    params = net.init(jax.random.PRNGKey(0))
    x = jax.random.normal(jax.random.PRNGKey(1), (4, obs_size))
    per_head = disc.input_gradients(net.apply, params, x, "per_head")  # [H, N, D]
    np.testing.assert_allclose(net.head_grad_sq_norms(params, x), jnp.sum(per_head**2, -1).T, rtol=1e-5, atol=1e-7)
    # The penalty and its parameter gradient (double backward) agree with the backward passes.
    gp = lambda p, fn: disc.gradient_penalty(net.apply, p, x, "per_head", fn)  # noqa: E731
    np.testing.assert_allclose(gp(params, net.head_grad_sq_norms), gp(params, None), rtol=1e-5)
    fast, slow = (jax.grad(gp)(params, fn) for fn in (net.head_grad_sq_norms, None))
    for a, b in zip(jax.tree.leaves(fast), jax.tree.leaves(slow)):
        np.testing.assert_allclose(a, b, rtol=1e-4, atol=1e-6)


def test_interpolate_per_sample_alpha():
    pol = jnp.zeros((64, 3))
    ref = jnp.ones((64, 3))
    x_hat = disc.interpolate(jax.random.PRNGKey(0), pol, ref)
    alpha = x_hat[:, 0]
    np.testing.assert_allclose(x_hat, jnp.broadcast_to(alpha[:, None], x_hat.shape))
    assert (alpha >= 0).all() and (alpha <= 1).all() and jnp.std(alpha) > 0.1


def test_disc_reward_is_mean_of_clipped_heads():
    logits = jnp.array([[[2.0, -0.5, 0.3, -4.0]], [[0.1, 0.2, 0.3, 0.4]]])  # [2, 1, 4]
    np.testing.assert_allclose(disc.disc_reward(logits), [[(1.0 - 0.5 + 0.3 - 1.0) / 4], [0.25]], rtol=1e-6)


def test_disc_loss_rejects_unknown_mode():
    apply_fn, params = _linear_disc()
    with pytest.raises(ValueError, match="gp_mode"):
        zeros = jnp.zeros((2, 4))
        disc.disc_loss(apply_fn, params, zeros, zeros, jax.random.PRNGKey(0), gp_mode="bogus")


# The discriminator's loss switch (``loss``: hinge, lsgan, bce).

_POL_LOGITS = np.array([-0.5, 2.0], np.float32)  # [H] logits of every policy sample
_REF_LOGITS = np.array([0.5, -3.0], np.float32)  # [H] logits of every reference sample


def _selector_disc():
    """Logits ``pol + x_0 (ref - pol)``: fixed logits at x_0 = 0 (policy) and 1 (reference)."""
    params = {"pol": jnp.asarray(_POL_LOGITS), "ref": jnp.asarray(_REF_LOGITS)}
    return (lambda p, x: p["pol"] + x[:, :1] * (p["ref"] - p["pol"])), params


def _sigmoid(z):
    return 1.0 / (1.0 + np.exp(-np.asarray(z, np.float64)))


@pytest.mark.parametrize("gp_mode", ["per_head", "sum_heads"])
@pytest.mark.parametrize(
    "loss_name,expected",
    [
        # mean_h relu(1 + pol) = (0.5 + 3) / 2; mean_h relu(1 - ref) = (0.5 + 4) / 2
        ("hinge", 1.75 + 2.25),
        # mean_h (ref - 1)^2 = (0.25 + 16) / 2; mean_h (pol + 1)^2 = (0.25 + 9) / 2
        ("lsgan", 8.125 + 4.625),
        # mean_h -log sigmoid(ref) + mean_h -log(1 - sigmoid(pol))
        ("bce", np.mean(-np.log(_sigmoid(_REF_LOGITS))) + np.mean(-np.log(1 - _sigmoid(_POL_LOGITS)))),
    ],
)
def test_disc_losses_hand_computed_on_fixed_logits(loss_name, expected, gp_mode):
    apply_fn, params = _selector_disc()
    pol = np.zeros((4, 3), np.float32)
    ref = np.zeros((4, 3), np.float32)
    ref[:, 0] = 1.0
    # d logits / d x_0 = ref - pol = [1, -5] everywhere: per head ((1-1)^2 + (5-1)^2) / 2 = 8,
    # summed heads (|1 - 5| - 1)^2 = 9.
    gp = 8.0 if gp_mode == "per_head" else 9.0
    loss, metrics = disc.disc_loss(
        apply_fn, params, pol, ref, jax.random.PRNGKey(0), gp_weight=10.0, gp_mode=gp_mode, loss=loss_name
    )
    np.testing.assert_allclose(metrics[f"{loss_name}_loss"], expected, rtol=1e-5)
    np.testing.assert_allclose(metrics["gradient_penalty"], gp, rtol=1e-5)
    np.testing.assert_allclose(loss, expected + 10.0 * gp, rtol=1e-5)
    np.testing.assert_allclose(metrics["accuracy"], 0.5)  # one head right on each side


def test_disc_rewards_hand_computed():
    logits = jnp.asarray([_POL_LOGITS, [-3.0, 50.0], [1.0, 1.0]])  # [3, H=2]
    np.testing.assert_allclose(disc.disc_reward(logits, "hinge"), [(-0.5 + 1) / 2, 0.0, 1.0], rtol=1e-6)
    # max(0, 1 - (D - 1)^2 / 4): 1 - 2.25/4, 1 - 1/4; 0 (floored), 0 (floored); 1, 1.
    np.testing.assert_allclose(disc.disc_reward(logits, "lsgan"), [(0.4375 + 0.75) / 2, 0.0, 1.0], rtol=1e-6)
    # -log max(1 - sigmoid(D), 1e-4): 1 - sigmoid(50) underflows, the clip pays log 1e4.
    bce = lambda z: -np.log(np.maximum(1 - _sigmoid(z), 1e-4))  # noqa: E731
    np.testing.assert_allclose(
        disc.disc_reward(logits, "bce"), [bce(_POL_LOGITS).mean(), (bce(-3.0) + np.log(1e4)) / 2, bce(1.0)], rtol=1e-5
    )
    assert (np.asarray(disc.disc_reward(logits, "bce")) >= 0).all()
    np.testing.assert_allclose(disc.disc_reward(jnp.full((1, 3), 1e4), "bce"), [np.log(1e4)], rtol=1e-6)


@pytest.mark.parametrize("loss_name", disc.LOSSES)
def test_disc_reward_rises_with_reference_likeness(loss_name):
    """Every head's logit moved towards the reference target pays at least as much, strictly
    more between the targets (-1 and +1), and never less than ``MIN_REWARD``."""
    base = jax.random.uniform(jax.random.PRNGKey(0), (7, 5), minval=-0.2, maxval=0.2)
    shifts = jnp.linspace(-4.0, 0.8, 97)  # up to the reference target 1 (lsgan's peak)
    r = np.asarray(jax.vmap(lambda t: disc.disc_reward(base + t, loss_name))(shifts))  # [97, 7]
    assert (np.diff(r, axis=0) >= 0).all()
    between = (shifts[:-1] >= -0.8) & (shifts[1:] <= 0.8)
    assert (np.diff(r, axis=0)[np.asarray(between)] > 0).all()
    assert r.min() >= disc.MIN_REWARD[loss_name]
    np.testing.assert_allclose(
        disc.disc_reward(jnp.full((1, 3), -50.0), loss_name), [disc.MIN_REWARD[loss_name]], atol=1e-6
    )
    # One head more reference-like raises the ensemble's reward.
    zero = jnp.zeros((1, 5))
    one = zero.at[0, 2].set(0.5)
    assert float(disc.disc_reward(one, loss_name)[0]) > float(disc.disc_reward(zero, loss_name)[0])


@pytest.mark.parametrize("loss_name", disc.LOSSES)
def test_disc_losses_fall_when_training_on_separable_blobs(loss_name):
    import optax

    net = networks.make_discriminator_network(6, num_heads=4, hidden_sizes=(16, 8))
    params = net.init(jax.random.PRNGKey(0))
    k_pol, k_ref, k_gp = jax.random.split(jax.random.PRNGKey(1), 3)
    pol = jax.random.normal(k_pol, (64, 6)) - 1.5
    ref = jax.random.normal(k_ref, (64, 6)) + 1.5

    def loss_fn(p):
        return disc.disc_loss(net.apply, p, pol, ref, k_gp, 10.0, "sum_heads", loss=loss_name)

    opt = optax.adam(3e-2)
    state = opt.init(params)
    loss0, m0 = loss_fn(params)
    p = params
    for _ in range(15):
        grads = jax.grad(lambda q: loss_fn(q)[0])(p)
        updates, state = opt.update(grads, state, p)
        p = optax.apply_updates(p, updates)
    loss1, m1 = loss_fn(p)
    # Measured: hinge 2.38 -> 0.62, lsgan 3.50 -> 0.39, bce 1.66 -> 0.91; accuracy 0.95/0.98/0.87.
    assert float(loss1) < float(loss0)
    assert float(m1[f"{loss_name}_loss"]) < 0.75 * float(m0[f"{loss_name}_loss"])
    assert float(m1["accuracy"]) > 0.8
    reward = lambda x: jnp.mean(disc.disc_reward(net.apply(p, x), loss_name))  # noqa: E731
    assert float(reward(ref)) > float(reward(pol))


def test_default_hinge_matches_the_previous_numbers():
    """Golden values from ``disc_loss`` / ``disc_reward`` before the loss switch existed."""
    net = networks.make_discriminator_network(6, num_heads=32, hidden_sizes=(16, 8))
    params = net.init(jax.random.PRNGKey(0))
    pol = jax.random.normal(jax.random.PRNGKey(1), (5, 6))
    ref = 0.5 + jax.random.normal(jax.random.PRNGKey(3), (5, 6))
    golden = {
        "per_head": {
            "loss": 8.702189445495605,
            "hinge_loss": 1.9867264032363892,
            "gradient_penalty": 0.6715462803840637,
        },
        "sum_heads": {
            "loss": 2.438039779663086,
            "hinge_loss": 1.9867264032363892,
            "gradient_penalty": 0.04513133317232132,
        },
    }
    for gp_mode, fn in (("per_head", net.head_grad_sq_norms), ("sum_heads", None)):
        args = (net.apply, params, pol, ref, jax.random.PRNGKey(2), 10.0, gp_mode, fn)
        loss, m = disc.disc_loss(*args)
        loss_h, m_h = disc.disc_loss(*args, loss="hinge")
        assert set(m) == {"loss", "hinge_loss", "gradient_penalty", "policy_logit", "ref_logit", "accuracy"}
        for k, v in golden[gp_mode].items():
            # float32 rounding differs by an ulp or two between CPUs (AMD vs Intel AVX-512 hosts)
            np.testing.assert_allclose(m[k], v, rtol=1e-5, err_msg=f"{gp_mode} {k}")
        np.testing.assert_allclose(m["accuracy"], 0.528125, rtol=1e-6)
        np.testing.assert_array_equal(loss, loss_h)
        # The very ops of the old body: hinge + gp_weight * gradient penalty, bit for bit.
        x_hat = disc.interpolate(jax.random.PRNGKey(2), pol, ref)
        old = disc.hinge_loss(net.apply(params, pol), net.apply(params, ref)) + 10.0 * disc.gradient_penalty(
            net.apply, params, x_hat, gp_mode, fn
        )
        np.testing.assert_array_equal(loss, old)
    logits = 20.0 * net.apply(params, pol)
    r = disc.disc_reward(logits)
    np.testing.assert_allclose(
        r,
        [-0.02021697908639908, -0.3333064913749695, -0.0938066691160202, -0.08793289959430695, -0.03819826617836952],
        rtol=1e-5,
    )
    np.testing.assert_array_equal(r, disc.disc_reward(logits, "hinge"))
    np.testing.assert_array_equal(r, jnp.mean(jnp.clip(logits, -1.0, 1.0), axis=-1))


def test_unknown_disc_loss_is_rejected_with_the_valid_names():
    from jaxmotion.training.learner import DiscConfig

    apply_fn, params = _linear_disc()
    zeros = jnp.zeros((2, 4))
    key = jax.random.PRNGKey(0)
    for call in (
        lambda: DiscConfig(loss="wgan"),
        lambda: disc.disc_loss(apply_fn, params, zeros, zeros, key, loss="wgan"),
        lambda: disc.disc_reward(zeros, "wgan"),
    ):
        with pytest.raises(ValueError, match="'hinge', 'lsgan', 'bce'.*'wgan'"):
            call()
    assert DiscConfig().loss == "hinge"


@pytest.mark.parametrize("loss_name,accepted", [("hinge", False), ("lsgan", True), ("bce", True)])
def test_learner_reward_floor_follows_the_disc_loss(loss_name, accepted):
    """A fall paying -0.5 is below the lsgan and bce floors (0), not below the hinge's (-1)."""
    from jaxmotion.envs.humanoid import EnvConfig, GroupConfig, HumanoidEnv
    from jaxmotion.motion import MotionLib, make_test_clip
    from jaxmotion.training.learner import DiscConfig, Learner, PPOConfig, TrainConfig

    stand = MotionLib.from_clips([make_test_clip(10, 30.0)])
    env_cfg = EnvConfig(groups=(GroupConfig(name="full"),))
    ppo_cfg = PPOConfig(terminate_reward=-0.5, num_envs=4, horizon=4, minibatch_size=16)
    cfg = TrainConfig(env=env_cfg, ppo=ppo_cfg, disc=DiscConfig(minibatch_size=16, loss=loss_name))

    def make():
        return Learner(cfg, env=HumanoidEnv(env_cfg, motion_libs=(stand,), init_lib=stand))

    assert Learner.MIN_REWARD == -1.0  # the default (hinge) loss's
    if accepted:
        assert make().MIN_REWARD == disc.MIN_REWARD[loss_name] == 0.0
    else:
        with pytest.raises(ValueError, match="terminate_reward"):
            make()


# --------------------------------------------------------------------------------------------
# Observation normaliser


def test_normalizer_matches_numpy_with_mask():
    rng = np.random.default_rng(0)
    state = normalizer.normalizer_init(4)
    seen = []
    for i in range(5):
        batch = rng.normal(10.0 * i, 1.0 + i, size=(3, 7, 4)).astype(np.float32)
        mask = (rng.random((3, 7)) < 0.7).astype(np.float32)
        state = normalizer.normalizer_update(state, batch, mask)
        seen.append(batch[mask > 0])
    allx = np.concatenate(seen)
    np.testing.assert_allclose(state.count, len(allx))
    np.testing.assert_allclose(state.mean, allx.mean(0), rtol=1e-5, atol=1e-5)
    np.testing.assert_allclose(state.std, allx.std(0), rtol=1e-5)
    x = rng.normal(size=(2, 4)).astype(np.float32) * 30
    np.testing.assert_allclose(normalizer.normalize(state, x, clip=None), (x - allx.mean(0)) / allx.std(0), rtol=1e-4)
    np.testing.assert_allclose(normalizer.denormalize(state, normalizer.normalize(state, x, clip=None)), x, rtol=1e-5)


def test_normalizer_identity_clip_and_empty_batch():
    state = normalizer.normalizer_init(2)
    x = jnp.array([[10.0, -0.5]])
    np.testing.assert_allclose(normalizer.normalize(state, x, clip=None), x)
    np.testing.assert_allclose(normalizer.normalize(state, x), [[5.0, -0.5]])
    state = normalizer.normalizer_update(state, jnp.array([[1.0, 2.0], [3.0, 2.0]]))
    np.testing.assert_allclose(state.mean, [2.0, 2.0])
    # std = sqrt(var + 1e-5): a constant feature gets std ~3.2e-3, not a 1e-6 floor.
    np.testing.assert_allclose(state.std, np.sqrt([1.0 + 1e-5, 1e-5]), rtol=1e-6)
    same = normalizer.normalizer_update(state, jnp.ones((3, 2)) * 100, mask=jnp.zeros(3))
    jax.tree.map(np.testing.assert_allclose, same, state)
