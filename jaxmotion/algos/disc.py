"""Discriminator-ensemble loss (hinge + gradient penalty) and reward (Xu et al. 2023, Eqs. 2, 5).

A discriminator ensemble maps an observation ``x [D]`` to ``H`` logits (heads). Reference
(motion-capture) observations are pushed above +1 and policy observations below -1 with a hinge
loss, and a gradient penalty at random interpolates keeps the critic close to 1-Lipschitz
(WGAN-GP style, target norm 1)::

    L_hinge = mean_h [ mean_n relu(1 + D_h(x_policy)) + mean_n relu(1 - D_h(x_ref)) ]
    x_hat   = alpha * x_ref + (1 - alpha) * x_policy,     alpha ~ U(0, 1) per sample
    L_gp    = mean_n mean_h (|grad_x D_h(x_hat)|_2 - 1)^2      gp_mode="per_head"  (Eq. 2)
    L_gp    = mean_n (|grad_x sum_h D_h(x_hat)|_2 - 1)^2       gp_mode="sum_heads" (authors' code)
    L       = L_hinge + gp_weight * L_gp

Both terms are averaged (not summed) over heads, so the loss scale does not depend on ``H``.
The reward of a group is the ensemble mean of the clipped logits (Eq. 5), ``mean_h clip(D_h,
-1, 1)``.

``loss`` switches the prediction term and the reward (``LOSSES``); each is applied per head and
averaged over samples and heads like the hinge, and the gradient penalty above is the same for
all three::

    "hinge": L_hinge as above;            r = mean_h clip(D_h, -1, 1)              in [-1, 1]
    "lsgan": mean_h [ mean_m (D_h(x_ref) - 1)^2 + mean_n (D_h(x_policy) + 1)^2 ]
                                           r = mean_h max(0, 1 - (D_h - 1)^2 / 4)    in [0, 1]
    "bce":   mean_h [ mean_m -log sigmoid(D_h(x_ref)) + mean_n -log sigmoid(-D_h(x_policy)) ]
                                           r = mean_h -log max(1 - sigmoid(D_h), 1e-4)
                                                                          in [0, log 1e4 ~ 9.21]

"lsgan" is the least-squares GAN of the AMP paper (Peng et al. 2021). "bce" is the binary
cross-entropy of AMP's released isaacgym code as PHC (ZhengyiLuo/PHC) inherits it, reward clip
included; that code also halves the sum of the two terms and adds logit and weight-decay
regularisers, not done here. Both AMP and PHC penalise ``|grad_x D|^2`` on reference samples
(zero-centred); here every loss keeps the interpolate penalty above (``gp_mode``). The lsgan
reward peaks at ``D = 1`` (the reference target) and falls again above it, as in AMP.

The per-sample input gradients are taken with one backward pass per head through the batched
forward pass, which assumes the discriminator treats samples independently (no batch
statistics), true of ``nets.networks.DiscriminatorEnsemble``. For that network the per-head
squared norms can instead come from ``networks.head_input_grad_sq_norms`` (``sq_norms_fn``): the
same values from the chain rule written out, with about 40% fewer multiply-adds, which matters
because the per-head penalty is the largest learning cost per sample after PPO.
"""

from __future__ import annotations

from typing import Any
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np

from jaxmotion.config.errors import ConfigError

Params = Any
GP_MODES = ("per_head", "sum_heads")
LOSSES = ("hinge", "lsgan", "bce")
BCE_REWARD_FLOOR = 1e-4
"""The ``"bce"`` reward's clip: ``1 - sigmoid(D)`` is floored here (reward at most ``log 1e4``)."""
MIN_REWARD = {"hinge": -1.0, "lsgan": 0.0, "bce": 0.0}
"""The lowest reward ``disc_reward`` can pay per step, by loss."""


def check_loss(loss: str) -> None:
    """Raises a ``ConfigError`` (a ``ValueError``) naming the valid losses unless ``loss`` is one of
    ``LOSSES``."""
    if loss not in LOSSES:
        names = ", ".join(map(repr, LOSSES))
        raise ConfigError(f"disc.loss={loss}: must be one of {names}, not {loss!r}")


def hinge_loss(policy_logits: jax.Array, ref_logits: jax.Array) -> jax.Array:
    """Hinge loss averaged over samples and heads.

    Args:
      policy_logits: ``[N, H]`` logits on policy observations (pushed below -1).
      ref_logits: ``[M, H]`` logits on reference observations (pushed above +1).

    Returns:
      ``[]`` ``mean_h [mean_n relu(1 + D_policy) + mean_m relu(1 - D_ref)]``.
    """
    return jnp.mean(jax.nn.relu(1.0 + policy_logits)) + jnp.mean(jax.nn.relu(1.0 - ref_logits))


def lsgan_loss(policy_logits: jax.Array, ref_logits: jax.Array) -> jax.Array:
    """Least-squares GAN loss of AMP averaged over samples and heads.

    Args:
      policy_logits: ``[N, H]`` logits on policy observations (target -1).
      ref_logits: ``[M, H]`` logits on reference observations (target +1).

    Returns:
      ``[]`` ``mean_h [mean_m (D_ref - 1)^2 + mean_n (D_policy + 1)^2]``.
    """
    return jnp.mean(jnp.square(ref_logits - 1.0)) + jnp.mean(jnp.square(policy_logits + 1.0))


def bce_loss(policy_logits: jax.Array, ref_logits: jax.Array) -> jax.Array:
    """Binary cross-entropy on logits (reference label 1, policy label 0), averaged over samples
    and heads.

    Args:
      policy_logits: ``[N, H]`` logits on policy observations (label 0).
      ref_logits: ``[M, H]`` logits on reference observations (label 1).

    Returns:
      ``[]`` ``mean_h [mean_m -log sigmoid(D_ref) + mean_n -log sigmoid(-D_policy)]``, with
      ``log_sigmoid`` (finite at any logit).
    """
    return -jnp.mean(jax.nn.log_sigmoid(ref_logits)) - jnp.mean(jax.nn.log_sigmoid(-policy_logits))


_PREDICTION_LOSSES = {"hinge": hinge_loss, "lsgan": lsgan_loss, "bce": bce_loss}


def _safe_norm(x: jax.Array, axis: int = -1) -> jax.Array:
    # The epsilon keeps the double-backward finite where the input gradient is exactly zero.
    return jnp.sqrt(jnp.sum(jnp.square(x), axis=axis) + 1e-12)


def input_gradients(
    apply_fn: Callable[[Params, jax.Array], jax.Array],
    params: Params,
    x: jax.Array,
    gp_mode: str = "per_head",
) -> jax.Array:
    """Gradient of the logits with respect to each sample's input.

    Args:
      apply_fn: ``(params, x [N, D]) -> logits [N, H]``.
      params: discriminator parameters.
      x: ``[N, D]`` inputs.
      gp_mode: ``"per_head"`` for every head's gradient, ``"sum_heads"`` for the gradient of the
        sum of the heads.

    Returns:
      ``[H, N, D]`` for ``"per_head"``, ``[N, D]`` for ``"sum_heads"``.
    """
    logits, vjp_fn = jax.vjp(lambda inputs: apply_fn(params, inputs), x)
    if gp_mode == "sum_heads":
        return vjp_fn(jnp.ones_like(logits))[0]
    if gp_mode == "per_head":
        num_heads = logits.shape[-1]
        cotangents = jnp.broadcast_to(jnp.eye(num_heads, dtype=logits.dtype)[:, None, :], (num_heads,) + logits.shape)
        return jax.vmap(lambda ct: vjp_fn(ct)[0])(cotangents)
    raise ValueError(f"gp_mode must be one of {GP_MODES}, got {gp_mode!r}")


def gradient_penalty(
    apply_fn: Callable[[Params, jax.Array], jax.Array],
    params: Params,
    x: jax.Array,
    gp_mode: str = "per_head",
    sq_norms_fn: Callable[[Params, jax.Array], jax.Array] | None = None,
) -> jax.Array:
    """``[]`` mean over samples (and heads) of ``(|grad_x D(x)|_2 - 1)^2`` at the given inputs.

    Args:
      apply_fn: ``(params, x [N, D]) -> logits [N, H]``.
      params: discriminator parameters.
      x: ``[N, D]`` points at which to penalise (the interpolates).
      gp_mode: ``"per_head"`` (Eq. 2) or ``"sum_heads"`` (authors' code).
      sq_norms_fn: optional ``(params, x) -> [N, H]`` squared per-head gradient norms, used
        instead of per-head backward passes in ``"per_head"`` mode.
    """
    if gp_mode == "per_head" and sq_norms_fn is not None:
        norms = jnp.sqrt(sq_norms_fn(params, x) + 1e-12)
    else:
        norms = _safe_norm(input_gradients(apply_fn, params, x, gp_mode))
    return jnp.mean(jnp.square(norms - 1.0))


def interpolate(rng: jax.Array, policy_obs: jax.Array, ref_obs: jax.Array) -> jax.Array:
    """``[N, D]`` ``alpha * ref + (1 - alpha) * policy`` with ``alpha ~ U(0, 1)`` per sample."""
    alpha = jax.random.uniform(rng, (policy_obs.shape[0],) + (1,) * (policy_obs.ndim - 1))
    return alpha * ref_obs + (1.0 - alpha) * policy_obs


def disc_loss(
    apply_fn: Callable[[Params, jax.Array], jax.Array],
    params: Params,
    policy_obs: jax.Array,
    ref_obs: jax.Array,
    rng: jax.Array,
    gp_weight: float = 10.0,
    gp_mode: str = "per_head",
    sq_norms_fn: Callable[[Params, jax.Array], jax.Array] | None = None,
    loss: str = "hinge",
) -> tuple[jax.Array, dict[str, jax.Array]]:
    """Prediction loss (hinge by default) plus gradient penalty of one discriminator ensemble
    (module docstring).

    Args:
      apply_fn: ``(params, x [N, D]) -> logits [N, H]``; inputs already normalised.
      params: discriminator parameters (differentiate the loss with respect to these).
      policy_obs: ``[N, D]`` discriminator observations from policy rollouts.
      ref_obs: ``[N, D]`` discriminator observations from reference motions (same ``N``, paired
        for the interpolates).
      rng: key for the interpolation coefficients.
      gp_weight: weight of the gradient penalty.
      gp_mode: ``"per_head"`` (paper Eq. 2) or ``"sum_heads"`` (authors' code).
      sq_norms_fn: see ``gradient_penalty``.
      loss: the prediction loss, one of ``LOSSES`` (module docstring).

    Returns:
      ``(loss [], metrics)``, metrics a dict of scalars: ``loss``, ``<loss>_loss`` (e.g.
      ``hinge_loss``, the prediction term), ``gradient_penalty``, ``policy_logit``,
      ``ref_logit`` (means over samples and heads), ``accuracy`` (fraction of logits on the
      correct side of 0, the decision boundary of all three losses).
    """
    if gp_mode not in GP_MODES:
        raise ValueError(f"gp_mode must be one of {GP_MODES}, got {gp_mode!r}")
    check_loss(loss)
    policy_logits = apply_fn(params, policy_obs)
    ref_logits = apply_fn(params, ref_obs)
    prediction = _PREDICTION_LOSSES[loss](policy_logits, ref_logits)
    x_hat = jax.lax.stop_gradient(interpolate(rng, policy_obs, ref_obs))
    gp = gradient_penalty(apply_fn, params, x_hat, gp_mode, sq_norms_fn)
    total = prediction + gp_weight * gp
    correct = jnp.concatenate([(policy_logits < 0).ravel(), (ref_logits > 0).ravel()])
    metrics = {
        "loss": total,
        f"{loss}_loss": prediction,
        "gradient_penalty": gp,
        "policy_logit": jnp.mean(policy_logits),
        "ref_logit": jnp.mean(ref_logits),
        "accuracy": jnp.mean(correct.astype(jnp.float32)),
    }
    return total, jax.tree.map(jax.lax.stop_gradient, metrics)


def disc_reward(logits: jax.Array, loss: str = "hinge") -> jax.Array:
    """``[..., H]`` ensemble logits -> ``[...]`` reward, the mean over heads of a per-head reward.

    Args:
      logits: ``[..., H]`` discriminator logits.
      loss: the loss the discriminator is trained with, one of ``LOSSES``:
        ``"hinge"``: ``mean_h clip(D_h, -1, 1)`` (Eq. 5), in ``[-1, 1]``;
        ``"lsgan"``: ``mean_h max(0, 1 - (D_h - 1)^2 / 4)`` (AMP), in ``[0, 1]``;
        ``"bce"``: ``mean_h -log max(1 - sigmoid(D_h), 1e-4)`` (AMP's and PHC's code), computed as
        ``min(-log_sigmoid(-D_h), -log 1e-4)``: the clip at ``BCE_REWARD_FLOOR`` keeps it finite,
        in ``[0, log 1e4 ~ 9.21]``.

    Returns:
      ``[...]`` rewards, never below ``MIN_REWARD[loss]``.
    """
    check_loss(loss)
    if loss == "lsgan":
        per_head = jnp.maximum(0.0, 1.0 - 0.25 * jnp.square(logits - 1.0))
    elif loss == "bce":
        per_head = jnp.minimum(-jax.nn.log_sigmoid(-logits), -np.log(BCE_REWARD_FLOOR))
    else:
        per_head = jnp.clip(logits, -1.0, 1.0)
    return jnp.mean(per_head, axis=-1)
