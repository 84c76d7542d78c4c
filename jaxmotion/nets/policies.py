"""Policies behind one interface: the learner asks a policy for its action distribution and never
branches on how the policy is built.

A policy has learnable parameters and may condition on a per-step input of its own (``extra``),
computed when acting from frozen state the policy carries (``TrainState.meta``) and stored in the
rollout, because the PPO ratio depends on it:

* ``init(rng) -> params``
* ``extra(frozen, obs, rng) -> [..., extra_size]``: what the policy conditions on besides the
  normalised observation, from raw observations (``rng`` None: deterministic).
* ``dist(params, nobs, extra) -> (mean, log_std)``: the Gaussian over actions.
* ``weights(params, nobs) -> [..., weight_size]``: the composition weights an evaluator may plot
  (incremental learning's w per DoF, an expert gate), ``[..., 0]`` for a plain policy.
* ``carry_size`` and ``next_carry(params, nobs, extra) -> [..., carry_size]``: a recurrent state
  (0 features for a memoryless policy). The learner appends the carried state to ``extra`` (its
  last ``carry_size`` features), carries ``next_carry`` to the next step and resets it to 0 where
  an episode ends.

``GaussianPolicy`` is the MLP of every paper; ``IncrementalPolicy`` is Xu et al. 2023's Eq. 10,
``mu + w * stop_gradient(a_meta)`` over a frozen meta policy; ``nets.composer.ComposerPolicy``
weights K frozen primitives (PHC's multiplicative composer); ``nets.moe.MoEPolicy`` is Won et al.
2021's mixture of experts, whose smoothed gate is its carry. ``make_policy`` picks a policy that
builds on nothing frozen from ``NetConfig.policy``.
The frozen part a policy builds on makes it (``make_policy`` of ``training.meta.Meta`` and
``training.primitives.Primitives``), so the learner never names a kind of policy.
"""

from __future__ import annotations

from typing import Any
from collections.abc import Callable

import jax
import jax.numpy as jnp
from flax import struct

from jaxmotion.nets import networks as nets
from jaxmotion.nets.moe import MoEPolicy


@struct.dataclass
class PolicyState:
    """What acting needs, and nothing else: a frozen policy (``TrainState.meta``), an opponent in
    the pool, or one player's agent."""

    policy_params: Any
    obs_norm: Any
    meta: Any = None


class GaussianPolicy:
    """A Gaussian MLP: mean from the network, log std a learned vector or a network head."""

    extra_size = 0
    weight_size = 0
    carry_size = 0

    def __init__(self, obs_size: int, action_size: int, **net_kwargs: Any):
        self.net = nets.make_policy_network(obs_size, action_size, **net_kwargs)

    def init(self, rng: jax.Array) -> Any:
        return self.net.init(rng)

    def extra(self, frozen: Any, obs: jax.Array, rng: jax.Array | None) -> jax.Array:
        return jnp.zeros(obs.shape[:-1] + (0,), obs.dtype)

    def dist(self, params: Any, nobs: jax.Array, extra: jax.Array) -> tuple[jax.Array, jax.Array]:
        return self.net.apply(params, nobs)

    def weights(self, params: Any, nobs: jax.Array) -> jax.Array:
        return jnp.zeros(nobs.shape[:-1] + (0,), nobs.dtype)

    def next_carry(self, params: Any, nobs: jax.Array, extra: jax.Array) -> jax.Array:
        return no_carry(nobs)


class IncrementalPolicy:
    """``N(mu + w * stop_gradient(a_meta), sigma^2)`` (Xu et al. 2023, Eq. 10): ``a_meta`` is
    sampled from a frozen meta policy on its slice of the observation; ``mu``, ``sigma`` and ``w``
    (sigmoid, one per DoF, starting at ``meta_weight_bias``) are outputs of the new network.

    ``meta_act(frozen, obs, rng)`` is the frozen policy's action from raw observations of the new
    task (``training.meta.Meta.act``)."""

    def __init__(self, obs_size: int, action_size: int, meta_act: Callable, meta_weight_bias: float, **net_kwargs: Any):
        self.net = nets.make_policy_network(
            obs_size, action_size, meta_size=action_size, meta_weight_bias=meta_weight_bias, **net_kwargs
        )
        self.meta_act = meta_act
        self.extra_size = self.weight_size = action_size
        self.carry_size = 0

    def init(self, rng: jax.Array) -> Any:
        return self.net.init(rng)

    def extra(self, frozen: Any, obs: jax.Array, rng: jax.Array | None) -> jax.Array:
        return self.meta_act(frozen, obs, rng)

    def dist(self, params: Any, nobs: jax.Array, extra: jax.Array) -> tuple[jax.Array, jax.Array]:
        mu, log_std, w = self.net.apply(params, nobs)
        return mu + w * jax.lax.stop_gradient(extra), log_std

    def weights(self, params: Any, nobs: jax.Array) -> jax.Array:
        return self.net.apply(params, nobs)[2]

    def next_carry(self, params: Any, nobs: jax.Array, extra: jax.Array) -> jax.Array:
        return no_carry(nobs)


def no_carry(x: jax.Array) -> jax.Array:
    """The (empty) recurrent state of a memoryless policy: ``[..., 0]``."""
    return jnp.zeros(x.shape[:-1] + (0,), x.dtype)


def make_policy(env: Any, nc: Any) -> Any:
    """The policy ``NetConfig.policy`` names for ``env`` (``obs_size``, ``action_size``,
    ``body_obs_size``), when it builds on no frozen part: ``mlp`` a ``GaussianPolicy``, ``moe`` a
    ``nets.moe.MoEPolicy`` whose experts read the body features."""
    if nc.policy == "moe":
        return MoEPolicy(
            env.obs_size,
            env.action_size,
            env.body_obs_size,
            num_experts=nc.experts,
            alpha=nc.gate_alpha,
            expert_hidden=nc.expert_hidden,
            encoder_hidden=nc.encoder_hidden,
            init_log_std=nc.init_log_std,
            encoder=nc.encoder,
        )
    return GaussianPolicy(
        env.obs_size,
        env.action_size,
        hidden_sizes=nc.policy_hidden,
        activation=nc.activation,
        state_dependent_std=nc.state_dependent_std,
        init_log_std=nc.init_log_std,
    )
