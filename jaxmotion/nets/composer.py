"""A composer of frozen primitive policies (PHC §3.2 "Multiplicative Control"; MCP, Peng et al. 2019).

K frozen Gaussian primitives ``N(mu_i(s), sigma_i(s)^2)`` each propose an action; a new network,
the composer, outputs K non-negative weights ``w_i(s)`` and only it is trained (PPO's gradient
reaches the weights, never a primitive: their outputs enter through ``extra``, computed from
frozen parameters and stored in the rollout). Two rules (``NetConfig.composer``):

* ``product`` (the paper, MCP's Eq. 6 with the variance where the paper writes sigma): the
  precision-weighted product of the primitives' Gaussians,
  ``1/sigma^2 = sum_i w_i / sigma_i^2`` and ``mu = sigma^2 * sum_i w_i mu_i / sigma_i^2``, per
  action DoF; ``w = sigmoid(.)`` as in MCP, starting at 0.5 each (the precision-weighted mean of
  the primitives). One-hot weights give primitive i exactly.
* ``sum`` (the authors' code, ``humanoid_im_mcp.py``): the unnormalised weighted sum of the
  primitives' means, ``mu = sum_i w_i mu_i``, ``w = relu(.)`` starting at 1/K each, with a fixed
  ``sigma = exp(init_log_std)`` on the joint targets. Departure: the code samples the weights
  (PPO's action is the K-vector) and applies the sum to the sample; here the noise is on the
  joint targets, so the action space stays the character's and evaluation, export and the
  rollout need no second kind of action.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any, Literal

import flax.linen as nn
import jax
import jax.numpy as jnp

from jaxmotion.nets import networks as nets

Rule = Literal["product", "sum"]
RULES: tuple[str, ...] = ("product", "sum")


def compose(
    rule: str, w: jax.Array, means: jax.Array, log_stds: jax.Array, log_std: jax.Array | None = None
) -> tuple[jax.Array, jax.Array]:
    """The composite Gaussian ``(mean [..., A], log_std [..., A])`` of K primitives.

    Args:
        rule: ``product`` or ``sum`` (module docstring).
        w: ``[..., K]`` non-negative weights; for ``product`` at least one positive.
        means, log_stds: ``[..., K, A]`` the primitives' Gaussians.
        log_std: ``[..., A]`` the ``sum`` rule's own log std (ignored by ``product``).
    """
    if rule == "product":
        prec = w[..., :, None] * jnp.exp(-2.0 * log_stds)  # [..., K, A]
        total = prec.sum(-2)
        # Shares of the precision (one-hot weights: exactly 1 and 0, the primitive's own mean).
        return ((prec / total[..., None, :]) * means).sum(-2), -0.5 * jnp.log(total)
    if rule == "sum":
        return (w[..., :, None] * means).sum(-2), jnp.broadcast_to(log_std, means.shape[:-2] + means.shape[-1:])
    raise ValueError(f"unknown composition rule {rule!r}; choose one of {RULES}")


class ComposerNet(nn.Module):
    """``obs [..., D] -> (w [..., K], log_std [A])``: an MLP whose weight head starts near
    constant (kernel U(+-1e-4)): sigmoid at 0.5 (``product``) or relu at 1/K (``sum``)."""

    num_primitives: int
    action_size: int
    rule: str = "product"
    hidden_sizes: tuple[int, ...] = (256, 256)
    activation: str = "relu"
    init_log_std: float = -2.9

    @nn.compact
    def __call__(self, obs: jax.Array) -> tuple[jax.Array, jax.Array]:
        h = nets.MLP(self.hidden_sizes, self.activation, name="torso")(obs)
        bias = 0.0 if self.rule == "product" else 1.0 / self.num_primitives
        z = nn.Dense(
            self.num_primitives,
            kernel_init=nets.symmetric_uniform(1e-4),
            bias_init=nn.initializers.constant(bias),
            name="weights",
        )(h)
        w = nn.sigmoid(z) if self.rule == "product" else nn.relu(z)
        log_std = self.param("log_std", nn.initializers.constant(self.init_log_std), (self.action_size,))
        return w, log_std


class ComposerPolicy:
    """The composable-policy interface (``nets/policies.py``) over K frozen primitives.

    ``primitive_dists(frozen, obs) -> (means, log_stds)``, both ``[..., K, A]``, is the frozen
    primitives' Gaussians at raw observations (``training.primitives.Primitives.dists``);
    ``extra`` stores them side by side (``[..., 2 K A]``)."""

    def __init__(
        self,
        obs_size: int,
        action_size: int,
        num_primitives: int,
        primitive_dists: Callable,
        rule: str = "product",
        hidden_sizes: tuple[int, ...] = (256, 256),
        activation: str = "relu",
        init_log_std: float = -2.9,
    ):
        if rule not in RULES:
            raise ValueError(f"unknown composition rule {rule!r}; choose one of {RULES}")
        self.obs_size, self.action_size, self.k, self.rule = obs_size, action_size, num_primitives, rule
        self.module = ComposerNet(num_primitives, action_size, rule, tuple(hidden_sizes), activation, init_log_std)
        self.primitive_dists = primitive_dists
        self.extra_size = 2 * num_primitives * action_size
        self.weight_size = num_primitives
        self.carry_size = 0

    def init(self, rng: jax.Array) -> Any:
        return self.module.init(rng, jnp.zeros((1, self.obs_size), jnp.float32))

    def extra(self, frozen: Any, obs: jax.Array, rng: jax.Array | None) -> jax.Array:
        means, log_stds = self.primitive_dists(frozen, obs)
        return jnp.concatenate([means, log_stds], -2).reshape(obs.shape[:-1] + (self.extra_size,))

    def split_extra(self, extra: jax.Array) -> tuple[jax.Array, jax.Array]:
        """``extra [..., 2 K A]`` back into (means, log_stds), each ``[..., K, A]``."""
        both = extra.reshape(extra.shape[:-1] + (2 * self.k, self.action_size))
        return both[..., : self.k, :], both[..., self.k :, :]

    def dist(self, params: Any, nobs: jax.Array, extra: jax.Array) -> tuple[jax.Array, jax.Array]:
        w, log_std = self.module.apply(params, nobs)
        means, log_stds = self.split_extra(jax.lax.stop_gradient(extra))
        return compose(self.rule, w, means, log_stds, log_std)

    def weights(self, params: Any, nobs: jax.Array) -> jax.Array:
        return self.module.apply(params, nobs)[0]

    def next_carry(self, params: Any, nobs: jax.Array, extra: jax.Array) -> jax.Array:
        return jnp.zeros(nobs.shape[:-1] + (0,), nobs.dtype)
