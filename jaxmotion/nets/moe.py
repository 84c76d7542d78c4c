"""A mixture of motor experts gated by a task encoder (Won et al. 2021, §4.1 and Fig. 4).

N experts (64-64 MLPs) see only the body state ``b`` (the leading, normalised part of the
observation); an encoder (an MLP, 128-128) sees the whole observation ``o = (b, g)`` and outputs N
weights ``omega_t`` in (-1, 1) (tanh, no normalisation; its last layer starts at scale 0.01, so
``omega ~ 0``, as the authors' code). The weights are smoothed over time,
``omega_hat_t = (1 - alpha) omega_t + alpha omega_hat_{t-1}``, with ``omega_hat`` starting at 0 in
every episode, and the action is ``N(sum_i omega_hat_i e_i(b), sigma^2)`` with a learned
state-independent ``sigma``.

``omega_hat_{t-1}`` is the policy's recurrent state (``carry_size = N``; with the paper's LSTM
boxing encoder, ``encoder='lstm'``, the LSTM's cell and hidden state follow it): the learner
carries it in the rollout, resets it at episode ends and stores it with each step (the last
``carry_size`` features of the step's ``extra``), so the PPO update recomputes exactly the
distribution that acted. Gradients do not flow back through time (the authors' RLlib code trains
the recurrent state over stored sequences by BPTT).

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

ENCODERS = ("mlp", "lstm")
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
    """``(nobs [..., D], memory [..., M]) -> (omega [..., N], expert means [..., N, A], log_std [A],
    memory)``. The ``mlp`` encoder is memoryless (``M`` = 0); the ``lstm`` encoder (the paper's
    boxing encoder, with one LSTM layer of ``encoder_hidden[0]`` units instead of two, then dense
    layers of the rest) carries its cell and hidden state (``M`` = 2 x units)."""

    num_experts: int
    action_size: int
    body_size: int
    expert_hidden: Sequence[int] = (64, 64)
    encoder_hidden: Sequence[int] = (128, 128)
    activation: str = "relu"
    init_log_std: float = -3.0
    encoder: str = "mlp"

    @property
    def memory_size(self) -> int:
        return 2 * self.encoder_hidden[0] if self.encoder == "lstm" else 0

    @nn.compact
    def __call__(self, nobs: jax.Array, memory: jax.Array) -> tuple[jax.Array, jax.Array, jax.Array, jax.Array]:
        means = Experts(self.num_experts, self.action_size, self.expert_hidden, self.activation, name="experts")(
            nobs[..., : self.body_size]
        )
        if self.encoder == "lstm":
            c, h = jnp.split(memory, 2, -1)
            (c, h), x = nn.OptimizedLSTMCell(self.encoder_hidden[0], name="encoder_lstm")((c, h), nobs)
            memory = jnp.concatenate([c, h], -1)
            x = nets.MLP(self.encoder_hidden[1:], self.activation, name="encoder")(x)
        else:
            x = nets.MLP(self.encoder_hidden, self.activation, name="encoder")(nobs)
        gate = nn.Dense(
            self.num_experts, kernel_init=nn.initializers.variance_scaling(1e-4, "fan_in", "uniform"), name="gate"
        )(x)
        log_std = self.param("log_std", nn.initializers.constant(self.init_log_std), (self.action_size,))
        return jnp.tanh(gate), means, log_std, memory


class MoEPolicy:
    """The composable-policy interface (``nets/policies.py``) for ``MoENet`` with smoothing
    ``alpha``; its carry is ``omega_hat_{t-1}`` [..., N], then the LSTM encoder's memory."""

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
        encoder: str = "mlp",
    ):
        if encoder not in ENCODERS:
            raise ValueError(f"unknown encoder {encoder!r}; choose one of {ENCODERS}")
        self.obs_size, self.alpha, self.n = obs_size, float(alpha), num_experts
        self.module = MoENet(
            num_experts,
            action_size,
            body_size,
            tuple(expert_hidden),
            tuple(encoder_hidden),
            activation,
            init_log_std,
            encoder,
        )
        self.carry_size = num_experts + self.module.memory_size
        # The gate an evaluator plots is the memoryless encoder's (a recurrent one needs its memory).
        self.weight_size = num_experts if encoder == "mlp" else 0

    def init(self, rng: jax.Array) -> Any:
        return self.module.init(rng, *self._inputs(jnp.zeros((1, self.obs_size), jnp.float32), None))

    def _inputs(self, nobs: jax.Array, extra: jax.Array | None) -> tuple[jax.Array, jax.Array]:
        """(nobs, the encoder's carried memory) from ``extra`` (None: a start's, zeros)."""
        m = self.module.memory_size
        if extra is None or m == 0:
            return nobs, jnp.zeros(nobs.shape[:-1] + (m,), nobs.dtype)
        return nobs, jax.lax.stop_gradient(extra[..., -m:])

    def _apply(self, params: Any, nobs: jax.Array, extra: jax.Array | None):
        return self.module.apply(params, *self._inputs(nobs, extra))

    def extra(self, frozen: Any, obs: jax.Array, rng: jax.Array | None) -> jax.Array:
        return jnp.zeros(obs.shape[:-1] + (0,), obs.dtype)

    def gate(self, omega: jax.Array, extra: jax.Array) -> jax.Array:
        """``omega_hat_t`` from this step's ``omega`` and the carried ``omega_hat_{t-1}`` (the
        carry's first ``N`` features in ``extra``, held constant for the gradient)."""
        start = extra.shape[-1] - self.carry_size
        prev = jax.lax.stop_gradient(extra[..., start : start + self.n])
        return (1.0 - self.alpha) * omega + self.alpha * prev

    def dist(self, params: Any, nobs: jax.Array, extra: jax.Array) -> tuple[jax.Array, jax.Array]:
        omega, means, log_std, _ = self._apply(params, nobs, extra)
        mean = jnp.einsum("...n,...na->...a", self.gate(omega, extra), means)
        return mean, jnp.broadcast_to(log_std, mean.shape)

    def next_carry(self, params: Any, nobs: jax.Array, extra: jax.Array) -> jax.Array:
        omega, _, _, memory = self._apply(params, nobs, extra)
        return jnp.concatenate([self.gate(omega, extra), memory], -1)

    def weights(self, params: Any, nobs: jax.Array) -> jax.Array:
        """The encoder's unsmoothed ``omega_t`` (what an evaluator plots of the gate; for the
        ``lstm`` encoder, none: ``[..., 0]``)."""
        return self._apply(params, nobs, None)[0][..., : self.weight_size]

    def experts(self, params: Any, nobs: jax.Array) -> jax.Array:
        """Every expert's mean action [..., N, A] (they read only the body features)."""
        return self._apply(params, nobs, None)[1]

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
