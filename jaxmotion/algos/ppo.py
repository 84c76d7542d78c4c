"""Multi-objective PPO losses (Xu et al. 2023, Eq. 9) with multi-head PopArt critics.

Each objective ``k`` has its own advantage ``A_k`` (``gae.compute_gae`` per critic head). The
advantages are standardised per objective over the whole rollout batch and summed with the
objective weights ``w_k`` (``combine_advantages``). The policy loss is PPO's clipped surrogate

* on the combined advantage, ``-mean_n min(rho A, clip(rho, 1-eps, 1+eps) A)`` with
  ``A = sum_k w_k Abar_k`` (paper Eq. 9, ``per_objective_clip=False``), or
* per objective, then summed, ``-mean_n sum_k min(rho w_k Abar_k, clip(rho) w_k Abar_k)``
  (the authors' code, ``per_objective_clip=True``).

The two agree when ``K = 1``, which is also how the single-objective ablation is run: the caller
sums the rewards into one objective (``K = 1``, weight 1).

The value loss is the MSE between the critic's normalised outputs and the PopArt-normalised
returns, averaged over samples and heads, with weight 0.5; there is no entropy term by default.
"""

from __future__ import annotations

from typing import Any
from collections.abc import Callable

import jax
import jax.numpy as jnp
import optax
from flax import struct

from jaxmotion.algos import popart

Params = Any
_LOG_2PI = jnp.log(2.0 * jnp.pi)


@struct.dataclass
class PPOBatch:
    """One minibatch of rollout data, flattened over time and envs.

    Attributes:
      obs: ``[N, ...]`` observations (any pytree with leading ``N``), already normalised.
      actions: ``[N, A]`` actions taken.
      log_probs: ``[N]`` log-probability of ``actions`` under the behaviour policy.
      advantages: ``[N, K]`` per-objective advantages, already standardised over the whole
        rollout batch (second output of ``combine_advantages``), not yet weighted.
      returns: ``[N, K]`` unnormalised return targets (``gae.compute_gae``).
    """

    obs: Any
    actions: jax.Array
    log_probs: jax.Array
    advantages: jax.Array
    returns: jax.Array


def gaussian_log_prob(mean: jax.Array, log_std: jax.Array, x: jax.Array) -> jax.Array:
    """Log-density of a diagonal Gaussian.

    Args:
      mean: ``[..., A]``.
      log_std: ``[..., A]`` (or broadcastable).
      x: ``[..., A]``.

    Returns:
      ``[...]`` log-density, summed over the action dimension.
    """
    z = (x - mean) * jnp.exp(-log_std)
    return jnp.sum(-0.5 * jnp.square(z) - log_std - 0.5 * _LOG_2PI, axis=-1)


def gaussian_entropy(log_std: jax.Array) -> jax.Array:
    """``[..., A]`` log std -> ``[...]`` entropy of the diagonal Gaussian."""
    return jnp.sum(log_std + 0.5 * (1.0 + _LOG_2PI), axis=-1)


def combine_advantages(
    advantages: jax.Array,
    weights: jax.Array,
    standardize: bool = True,
    eps: float = 1e-8,
    axis_name: str | None = None,
) -> tuple[jax.Array, jax.Array]:
    """Standardises each objective's advantage over the batch, then takes the weighted sum.

    ``Abar_k = (A_k - mean_n A_k) / (std_n A_k + eps)`` with the unbiased (``N - 1``) std, as in
    the authors' code (biased when ``N = 1``); ``A = sum_k w_k Abar_k``.

    Args:
      advantages: ``[N, K]`` per-objective advantages of the whole rollout batch.
      weights: ``[K]`` objective weights (summing to 1 by convention).
      standardize: if False, ``Abar_k = A_k``.
      eps: added to the std.
      axis_name: inside ``shard_map``, the mesh axis the batch is split over (equal shares):
        mean and std are those of every device's advantages together.

    Returns:
      ``(combined [N], standardised [N, K])``.
    """
    if standardize and axis_name:
        n = advantages.shape[0] * jax.lax.axis_size(axis_name)
        mean = jax.lax.pmean(jnp.mean(advantages, axis=0), axis_name)
        ss = jax.lax.psum(jnp.sum(jnp.square(advantages - mean), axis=0), axis_name)
        advantages = (advantages - mean) / (jnp.sqrt(ss / max(n - 1, 1)) + eps)
    elif standardize:
        ddof = 1 if advantages.shape[0] > 1 else 0
        mean = jnp.mean(advantages, axis=0)
        sd = jnp.std(advantages, axis=0, ddof=ddof)
        advantages = (advantages - mean) / (sd + eps)
    return advantages @ weights, advantages


def clipped_surrogate(
    log_ratio: jax.Array,
    advantages: jax.Array,
    weights: jax.Array,
    clip_eps: float = 0.2,
    per_objective_clip: bool = False,
) -> jax.Array:
    """PPO clipped surrogate loss (to minimise) on weighted per-objective advantages.

    Args:
      log_ratio: ``[N]`` ``log pi(a|s) - log pi_old(a|s)``.
      advantages: ``[N, K]`` standardised per-objective advantages ``Abar``.
      weights: ``[K]`` objective weights ``w``.
      clip_eps: ratio clip range.
      per_objective_clip: False: clip once on ``sum_k w_k Abar_k`` (Eq. 9). True: clip each
        ``w_k Abar_k`` term separately and sum (authors' code).

    Returns:
      ``[]`` ``-mean_n(surrogate)``.
    """
    ratio = jnp.exp(log_ratio)
    clipped = jnp.clip(ratio, 1.0 - clip_eps, 1.0 + clip_eps)
    weighted = advantages * weights  # [N, K]
    if per_objective_clip:
        surrogate = jnp.minimum(ratio[:, None] * weighted, clipped[:, None] * weighted)
        surrogate = jnp.sum(surrogate, axis=-1)
    else:
        adv = jnp.sum(weighted, axis=-1)
        surrogate = jnp.minimum(ratio * adv, clipped * adv)
    return -jnp.mean(surrogate)


def value_loss(values: jax.Array, targets: jax.Array) -> jax.Array:
    """``[N, K]`` normalised critic outputs and targets -> ``[]`` MSE averaged over N and K."""
    return jnp.mean(jnp.square(values - jax.lax.stop_gradient(targets)))


def ppo_losses(
    policy_params: Params,
    critic_params: Params,
    batch: PPOBatch,
    policy_apply: Callable[[Params, Any], tuple[jax.Array, jax.Array]],
    critic_apply: Callable[[Params, Any], jax.Array],
    weights: jax.Array,
    popart_state: popart.PopArtState | None = None,
    clip_eps: float = 0.2,
    value_coef: float = 0.5,
    entropy_coef: float = 0.0,
    per_objective_clip: bool = False,
) -> tuple[jax.Array, dict[str, jax.Array]]:
    """Total PPO loss of the policy and the multi-head critic on one minibatch.

    ``loss = policy_loss + value_coef * value_loss - entropy_coef * entropy``.

    Args:
      policy_params: parameters of the policy.
      critic_params: parameters of the critic.
      batch: the minibatch (``N`` samples, ``K`` objectives).
      policy_apply: ``(params, obs [N, ...]) -> (mean [N, A], log_std [N, A])``.
      critic_apply: ``(params, obs [N, ...]) -> values [N, K]`` in the normalised space.
      weights: ``[K]`` objective weights.
      popart_state: statistics that normalise ``batch.returns``; ``None`` means the critic
        predicts unnormalised returns (the w/o-PopArt ablation).
      clip_eps: PPO ratio clip range.
      value_coef: weight of the value loss.
      entropy_coef: weight of the entropy bonus.
      per_objective_clip: see ``clipped_surrogate``.

    Returns:
      ``(loss [], metrics)``, metrics a dict of scalars: ``loss``, ``policy_loss``,
      ``value_loss``, ``entropy``, ``approx_kl``, ``clip_fraction``, ``ratio_mean``.
    """
    mean, log_std = policy_apply(policy_params, batch.obs)
    log_prob = gaussian_log_prob(mean, log_std, batch.actions)
    log_ratio = log_prob - batch.log_probs
    policy_loss = clipped_surrogate(log_ratio, batch.advantages, weights, clip_eps, per_objective_clip)

    values = critic_apply(critic_params, batch.obs)
    targets = batch.returns
    if popart_state is not None:
        targets = popart.normalize(popart_state, targets)
    v_loss = value_loss(values, targets)

    entropy = jnp.mean(gaussian_entropy(jnp.broadcast_to(log_std, mean.shape)))
    loss = policy_loss + value_coef * v_loss - entropy_coef * entropy

    ratio = jnp.exp(log_ratio)
    metrics = {
        "loss": loss,
        "policy_loss": policy_loss,
        "value_loss": v_loss,
        "entropy": entropy,
        # k3 estimator of KL(old || new), low variance and non-negative (Schulman 2020).
        "approx_kl": jnp.mean(ratio - 1.0 - log_ratio),
        "clip_fraction": jnp.mean((jnp.abs(ratio - 1.0) > clip_eps).astype(jnp.float32)),
        "ratio_mean": jnp.mean(ratio),
    }
    metrics = jax.tree.map(jax.lax.stop_gradient, metrics)
    return loss, metrics


def _param_labels(params: dict) -> dict:
    """Optimiser group of every parameter of ``{"actor": ..., "critic": ...}``: its top-level key,
    except the policy's meta-weight head (``meta_weight``, incremental learning), its own group."""

    def label(path, _):
        keys = [getattr(k, "key", None) for k in path]
        return "meta_weight" if keys[0] == "actor" and "meta_weight" in keys else keys[0]

    return jax.tree_util.tree_map_with_path(label, params)


def make_optimizer(
    max_grad_norm: float, actor_lr: float, critic_lr: float, meta_weight_lr: float = 0.0
) -> optax.GradientTransformation:
    """Global-norm clipping, then Adam per group of ``{"actor": ..., "critic": ...}``. With
    ``meta_weight_lr`` > 0 the meta-weight head has its own rate; without it the optimiser keeps
    the two prefix-labelled groups it always had, so existing checkpoints keep their structure."""
    lrs = {"actor": actor_lr, "critic": critic_lr}
    labels = {"actor": "actor", "critic": "critic"}
    if meta_weight_lr > 0:
        lrs["meta_weight"], labels = meta_weight_lr, _param_labels
    return optax.chain(
        optax.clip_by_global_norm(max_grad_norm),
        optax.multi_transform({k: optax.adam(v) for k, v in lrs.items()}, labels),
    )
