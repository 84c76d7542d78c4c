"""A mixture of motor experts gated by a task encoder (Won et al. 2021, §4.1 and Fig. 4).

N experts (64-64 MLPs) see only the body state ``b`` (the leading, normalised part of the
observation); an encoder (an MLP, 128-128) sees the whole observation ``o = (b, g)`` and outputs N
weights ``omega_t`` in (-1, 1) (tanh, no normalisation; its last layer starts at scale 0.01, so
``omega ~ 0``, as the authors' code). The weights are smoothed over time,
``omega_hat_t = (1 - alpha) omega_t + alpha omega_hat_{t-1}``, with ``omega_hat`` starting at 0 in
every episode, and the action is ``N(sum_i omega_hat_i e_i(b), sigma^2)`` with a learned
state-independent ``sigma``.

``omega_hat_{t-1}`` is the policy's recurrent state (``carry_size = N``): the learner carries it in
the rollout, resets it at episode ends and stores it with each step (the last ``N`` features of the
step's ``extra``), so the PPO update recomputes exactly the distribution that acted. Gradients do
not flow back through time (the authors' RLlib code trains the gate over stored sequences by BPTT).

The experts are the motor *decoder* that imitation pretraining trains and a sport keeps
(``decoder_mask``; the transfer schedule of ``decoder_learns``), the encoder the part a sport
replaces.
"""

from __future__ import annotations

from typing import Any
from collections.abc import Sequence

import flax.linen as nn
import jax
import jax.numpy as jnp

from jaxmotion.nets import networks as nets

DECODER = ("experts", "log_std")
"""The parameters of the motor decoder (kept by a transfer, frozen in encoder-only phases)."""


class Experts(nn.Module):
    """N MLPs on one input, as batched matrix products: ``[..., D] -> [..., N, A]``. Each layer is
    initialised as PyTorch's ``nn.Linear`` (the authors' code), independently per expert."""

    num_experts: int
    action_size: int
    hidden_sizes: Sequence[int] = (64, 64)
    activation: str = "relu"

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        act = nets.get_activation(self.activation)
        h = jnp.broadcast_to(x[..., None, :], x.shape[:-1] + (self.num_experts, x.shape[-1]))
        for i, size in enumerate(tuple(self.hidden_sizes) + (self.action_size,)):
            fan_in = h.shape[-1]
            bound = fan_in**-0.5
            init = lambda k, s, lo=-bound, hi=bound: jax.random.uniform(k, s, jnp.float32, lo, hi)
            w = self.param(f"kernel_{i}", init, (self.num_experts, fan_in, size))
            b = self.param(f"bias_{i}", init, (self.num_experts, size))
            h = jnp.einsum("...nd,ndk->...nk", h, w) + b
            if i < len(self.hidden_sizes):
                h = act(h)
        return h


class MoENet(nn.Module):
    """``nobs [..., D] -> (omega [..., N], expert means [..., N, A], log_std [A])``."""

    num_experts: int
    action_size: int
    body_size: int
    expert_hidden: Sequence[int] = (64, 64)
    encoder_hidden: Sequence[int] = (128, 128)
    activation: str = "relu"
    init_log_std: float = -3.0

    @nn.compact
    def __call__(self, nobs: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array]:
        means = Experts(self.num_experts, self.action_size, self.expert_hidden, self.activation, name="experts")(
            nobs[..., : self.body_size]
        )
        h = nets.MLP(self.encoder_hidden, self.activation, name="encoder")(nobs)
        gate = nn.Dense(
            self.num_experts, kernel_init=nn.initializers.variance_scaling(1e-4, "fan_in", "uniform"), name="gate"
        )(h)
        log_std = self.param("log_std", nn.initializers.constant(self.init_log_std), (self.action_size,))
        return jnp.tanh(gate), means, log_std


class MoEPolicy:
    """The composable-policy interface (``nets/policies.py``) for ``MoENet`` with smoothing
    ``alpha``; its carry is ``omega_hat_{t-1}`` [..., N]."""

    extra_size = 0

    def __init__(
        self,
        obs_size: int,
        action_size: int,
        body_size: int,
        num_experts: int = 8,
        alpha: float = 0.9,
        expert_hidden: Sequence[int] = (64, 64),
        encoder_hidden: Sequence[int] = (128, 128),
        activation: str = "relu",
        init_log_std: float = -3.0,
    ):
        self.obs_size, self.alpha = obs_size, float(alpha)
        self.module = MoENet(
            num_experts, action_size, body_size, tuple(expert_hidden), tuple(encoder_hidden), activation, init_log_std
        )
        self.carry_size = self.weight_size = num_experts

    def init(self, rng: jax.Array) -> Any:
        return self.module.init(rng, jnp.zeros((1, self.obs_size), jnp.float32))

    def extra(self, frozen: Any, obs: jax.Array, rng: jax.Array | None) -> jax.Array:
        return jnp.zeros(obs.shape[:-1] + (0,), obs.dtype)

    def gate(self, omega: jax.Array, extra: jax.Array) -> jax.Array:
        """``omega_hat_t`` from this step's ``omega`` and the carried ``omega_hat_{t-1}`` (the
        last ``N`` features of ``extra``, held constant for the gradient)."""
        prev = jax.lax.stop_gradient(extra[..., -self.carry_size :])
        return (1.0 - self.alpha) * omega + self.alpha * prev

    def dist(self, params: Any, nobs: jax.Array, extra: jax.Array) -> tuple[jax.Array, jax.Array]:
        omega, means, log_std = self.module.apply(params, nobs)
        mean = jnp.einsum("...n,...na->...a", self.gate(omega, extra), means)
        return mean, jnp.broadcast_to(log_std, mean.shape)

    def next_carry(self, params: Any, nobs: jax.Array, extra: jax.Array) -> jax.Array:
        return self.gate(self.module.apply(params, nobs)[0], extra)

    def weights(self, params: Any, nobs: jax.Array) -> jax.Array:
        """The encoder's unsmoothed ``omega_t`` (what an evaluator plots of the gate)."""
        return self.module.apply(params, nobs)[0]

    def experts(self, params: Any, nobs: jax.Array) -> jax.Array:
        """Every expert's mean action [..., N, A] (they read only the body features)."""
        return self.module.apply(params, nobs)[1]

    def decoder_mask(self, params: Any) -> Any:
        """``params``' structure with True at the motor decoder's leaves (``DECODER``)."""
        return {"params": {k: jax.tree.map(lambda _, d=k in DECODER: d, v) for k, v in params["params"].items()}}


def decoder_learns(iteration: jax.Array, start: int, every: int) -> jax.Array:
    """Whether the decoder trains at ``iteration`` (Won et al. §4.4): not before ``start`` (the
    encoder alone learns first), then in turns of ``every`` iterations, end to end first, then
    encoder only (``every`` 0: end to end from ``start`` on). A function of the iteration count, so
    a resumed run is in the phase it stopped in."""
    after = iteration - start
    alternating = (after // max(every, 1)) % 2 == 0
    return (after >= 0) & (alternating if every > 0 else True)
