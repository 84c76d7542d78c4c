"""Policy, multi-head critic and discriminator-ensemble networks (Xu et al. 2023, Fig. 3).

Flax ``linen`` modules, each wrapped in an ``(init, apply)`` pair (``Network``) as in brax
``training/networks.py``. All take a flat observation ``[..., D]`` that the caller has already
normalised with ``algos.normalizer`` (the policy/critic state clipped to ±5, the discriminator
observations unclipped, each discriminator with its own statistics); normalisation is kept out of
``apply`` so the same statistics can be shared and updated in one place in the train state. The
authors' GRU encoders over frame windows are not modelled here; observations are flat.

Parameter layout (``params = network.init(rng)``, a ``{"params": ...}`` dict):

* ``GaussianPolicy``: ``torso/hidden_{i}``, ``mean``, and ``log_std`` (a ``Dense`` head when
  ``state_dependent_std``, else a ``[A]`` parameter).
* ``MultiHeadCritic``: ``torso/hidden_{i}`` and ``value_head`` with kernel ``[H, K]`` at
  ``params["params"]["value_head"]["kernel"]`` and bias ``[K]`` at
  ``params["params"]["value_head"]["bias"]``, the layer PopArt rescales (``value_head`` /
  ``replace_value_head``).
* ``DiscriminatorEnsemble``: ``torso/hidden_{i}`` and ``heads`` (kernel ``[H, N_heads]``).

``head_input_grad_sq_norms`` computes ``|grad_x D_k(x)|^2`` of every head of a
``DiscriminatorEnsemble`` from the chain rule written out as matrix products (the per-head gradient
penalty's inner quantity), with about 40% fewer multiply-adds than one backward pass per head.
"""

from __future__ import annotations

import dataclasses
from typing import Any
from collections.abc import Callable, Sequence

import flax.linen as nn
import jax
import jax.numpy as jnp

Params = Any
Initializer = Callable[..., jax.Array]

ACTIVATIONS: dict[str, Callable[[jax.Array], jax.Array]] = {
    "relu": nn.relu,
    "relu6": nn.relu6,
    "tanh": nn.tanh,
    "elu": nn.elu,
}

VALUE_HEAD = "value_head"

# PyTorch's nn.Linear default (kaiming_uniform with a=sqrt(5)): U(+-1/sqrt(fan_in)), the init of
# the authors' policy and critic layers.
torch_default_init = nn.initializers.variance_scaling(1.0 / 3.0, "fan_in", "uniform")


def symmetric_uniform(scale: float) -> Initializer:
    """Initializer drawing from ``U(-scale, scale)``."""

    def init(key: jax.Array, shape: Sequence[int], dtype: Any = jnp.float32) -> jax.Array:
        return jax.random.uniform(key, shape, dtype, -scale, scale)

    return init


def get_activation(name: str) -> Callable[[jax.Array], jax.Array]:
    """Looks up an activation in ``ACTIVATIONS`` with a clear error."""
    if name not in ACTIVATIONS:
        raise ValueError(f"unknown activation {name!r}; choose one of {sorted(ACTIVATIONS)}")
    return ACTIVATIONS[name]


class MLP(nn.Module):
    """Stack of ``Dense`` + activation layers; ``[..., D] -> [..., hidden_sizes[-1]]``."""

    hidden_sizes: Sequence[int]
    activation: str = "relu"
    kernel_init: Initializer = torch_default_init

    @nn.compact
    def __call__(self, x: jax.Array) -> jax.Array:
        act = get_activation(self.activation)
        for i, size in enumerate(self.hidden_sizes):
            x = act(nn.Dense(size, kernel_init=self.kernel_init, name=f"hidden_{i}")(x))
        return x


class GaussianPolicy(nn.Module):
    """Diagonal Gaussian policy: ``obs [..., D] -> (mean [..., A], log_std [..., A])``.

    Attributes:
      action_size: ``A``.
      hidden_sizes: widths of the hidden layers.
      activation: a key of ``ACTIVATIONS``.
      state_dependent_std: True (the authors' code): ``log_std`` is a linear head on the last
        hidden layer with weights ``U(+-1e-4)`` and bias ``init_log_std``. False: a learned
        state-independent ``[A]`` parameter initialised to ``init_log_std``.
      init_log_std: initial ``log_std`` (-3 gives sigma ~ 0.05).
      meta_size: > 0 for incremental learning (``training/meta.py``): a third output ``w [..., meta_size]``,
        a sigmoid head (``meta_weight``, weights U(+-1e-4), bias ``meta_weight_bias``) that
        weights a frozen meta policy's action; the ``mean`` head then starts at U(+-1e-4), so the
        new policy starts as the meta policy.
    """

    action_size: int
    hidden_sizes: Sequence[int] = (1024, 512)
    activation: str = "relu6"
    state_dependent_std: bool = True
    init_log_std: float = -3.0
    meta_size: int = 0
    meta_weight_bias: float = 3.0

    @nn.compact
    def __call__(self, obs: jax.Array) -> tuple[jax.Array, ...]:
        h = MLP(self.hidden_sizes, self.activation, name="torso")(obs)
        mean_init = symmetric_uniform(1e-4) if self.meta_size else torch_default_init
        mean = nn.Dense(self.action_size, kernel_init=mean_init, name="mean")(h)
        if self.state_dependent_std:
            log_std = nn.Dense(
                self.action_size,
                kernel_init=symmetric_uniform(1e-4),
                bias_init=nn.initializers.constant(self.init_log_std),
                name="log_std",
            )(h)
        else:
            log_std = self.param("log_std", nn.initializers.constant(self.init_log_std), (self.action_size,))
            log_std = jnp.broadcast_to(log_std, mean.shape)
        if not self.meta_size:
            return mean, log_std
        w = nn.Dense(
            self.meta_size,
            kernel_init=symmetric_uniform(1e-4),
            bias_init=nn.initializers.constant(self.meta_weight_bias),
            name="meta_weight",
        )(h)
        return mean, log_std, nn.sigmoid(w)


class MultiHeadCritic(nn.Module):
    """``K`` value heads on a shared torso: ``obs [..., D] -> values [..., K]`` (normalised space).

    The last layer is named ``VALUE_HEAD`` (kernel ``[H, K]``, bias ``[K]``) so PopArt can
    rescale it; its weights start at ``U(+-1e-4)`` and its bias at 0.
    """

    num_heads: int
    hidden_sizes: Sequence[int] = (1024, 512)
    activation: str = "relu6"
    hidden_init_scale: float = 0.0
    """0: hidden weights PyTorch's default, U(+-1/sqrt(fan_in)); > 0: U(+-hidden_init_scale)."""

    @nn.compact
    def __call__(self, obs: jax.Array) -> jax.Array:
        init = symmetric_uniform(self.hidden_init_scale) if self.hidden_init_scale > 0 else torch_default_init
        h = MLP(self.hidden_sizes, self.activation, kernel_init=init, name="torso")(obs)
        return nn.Dense(
            self.num_heads,
            kernel_init=symmetric_uniform(1e-4),
            bias_init=nn.initializers.zeros,
            name=VALUE_HEAD,
        )(h)


class DiscriminatorEnsemble(nn.Module):
    """Multi-head discriminator: ``obs [..., D] -> logits [..., num_heads]``.

    Every layer has orthogonal weights (gain ``hidden_gain`` for the hidden ones) and zero
    biases. Samples are processed independently (no batch statistics), which ``algos.disc``
    relies on for per-sample input gradients.
    """

    num_heads: int = 32
    hidden_sizes: Sequence[int] = (256, 128)
    activation: str = "relu"
    hidden_gain: float = 1.0
    """Orthogonal gain of the hidden layers (the heads keep gain 1)."""

    @nn.compact
    def __call__(self, obs: jax.Array) -> jax.Array:
        hidden = nn.initializers.orthogonal(self.hidden_gain)
        h = MLP(self.hidden_sizes, self.activation, kernel_init=hidden, name="torso")(obs)
        return nn.Dense(self.num_heads, kernel_init=nn.initializers.orthogonal(), name="heads")(h)


@jax.custom_vjp
def _row_quadratic_forms(a: jax.Array, v: jax.Array) -> jax.Array:
    """``[M]`` ``v_m^T a v_m`` for a symmetric ``a [H, H]`` and rows ``v [M, H]``.

    The custom backward uses the symmetry (``d/dv = 2 a v``, already computed in the forward),
    which saves one ``[M, H] x [H, H]`` product over what autodiff would do.
    """
    return jnp.sum(v * (v @ a), axis=-1)


def _row_quadratic_forms_fwd(a, v):
    av = v @ a
    return jnp.sum(v * av, axis=-1), (v, av)


def _row_quadratic_forms_bwd(res, ct):
    v, av = res
    vc = v * ct[:, None]
    return vc.T @ v, 2.0 * av * ct[:, None]


_row_quadratic_forms.defvjp(_row_quadratic_forms_fwd, _row_quadratic_forms_bwd)


def head_input_grad_sq_norms(params: Params, x: jax.Array, activation: str = "relu") -> jax.Array:
    """``[N, K]`` squared input-gradient norms ``|grad_x D_k(x_n)|^2`` of a ``DiscriminatorEnsemble``.

    With hidden kernels ``W_1 .. W_L`` (flax layout ``[in, out]``), head kernel ``W_h [H_L, K]``
    and activation derivatives ``s_i = act'(a_i)`` at the sample::

        grad_x D_k = W_1 diag(s_1) W_2 ... diag(s_L) W_h[:, k]

    Evaluated right to left for all heads at once as plain matrix products on ``[N*K, H_i]``
    rows. When the input is wider than the first hidden layer (``D > H_1``, the usual case), the
    last product is replaced by the quadratic form ``u^T (W_1^T W_1) u``, which costs ``H_1^2``
    instead of ``D H_1`` per row. Exact (to float rounding) and differentiable; the same values as
    ``K`` backward passes through ``apply``, which ``tests/test_algos.py`` checks.

    Args:
      params: ``DiscriminatorEnsemble`` parameters (``{"params": {"torso": ..., "heads": ...}}``).
      x: ``[N, D]`` inputs.
      activation: the ensemble's activation (a key of ``ACTIVATIONS``).
    """
    act = get_activation(activation)
    p = params["params"]
    layers = [p["torso"][f"hidden_{i}"] for i in range(len(p["torso"]))]
    head = p["heads"]["kernel"]  # [H_L, K]
    n, k = x.shape[0], head.shape[1]
    h, slopes = x, []
    for layer in layers:
        pre = h @ layer["kernel"] + layer["bias"]
        # act and its elementwise derivative in one pass; differentiable wherever act' is.
        h, slope = jax.jvp(act, (pre,), (jnp.ones_like(pre),))
        slopes.append(slope)  # [N, H_i]
    if not layers:  # a linear ensemble: the gradient of head k is W_h[:, k] for every sample
        return jnp.broadcast_to(jnp.sum(jnp.square(head), axis=0), (n, k))
    u = slopes[-1][:, None, :] * head.T[None]  # [N, K, H_L]
    for i in range(len(layers) - 1, 0, -1):
        u = (u @ layers[i]["kernel"].T) * slopes[i - 1][:, None, :]  # [N, K, H_{i-1}]
    u = u.reshape(n * k, -1)
    w1 = layers[0]["kernel"]  # [D, H_1]
    sq = _row_quadratic_forms(w1.T @ w1, u) if w1.shape[0] > w1.shape[1] else jnp.sum(jnp.square(u @ w1.T), axis=-1)
    return sq.reshape(n, k)


@dataclasses.dataclass(frozen=True)
class Network:
    """A network as a pair of pure functions.

    Attributes:
      init: ``rng -> params``.
      apply: ``(params, obs [..., D]) -> outputs``.
      head_grad_sq_norms: for a discriminator ensemble, ``(params, x [N, D]) -> [N, K]`` squared
        input-gradient norm of every head (the per-head gradient penalty), else ``None``.
    """

    init: Callable[[jax.Array], Params]
    apply: Callable[[Params, jax.Array], Any]
    head_grad_sq_norms: Callable[[Params, jax.Array], jax.Array] | None = None


def make_network(module: nn.Module, obs_size: int) -> Network:
    """Wraps a module taking ``[..., obs_size]`` inputs into an ``(init, apply)`` pair."""
    dummy = jnp.zeros((1, obs_size), jnp.float32)
    return Network(
        init=lambda rng: module.init(rng, dummy),
        apply=lambda params, obs: module.apply(params, obs),
    )


def make_policy_network(obs_size: int, action_size: int, **kwargs: Any) -> Network:
    """``GaussianPolicy(action_size, **kwargs)``; apply returns ``(mean, log_std)`` (and ``w``
    with ``meta_size``)."""
    return make_network(GaussianPolicy(action_size=action_size, **kwargs), obs_size)


def make_critic_network(obs_size: int, num_heads: int, **kwargs: Any) -> Network:
    """``MultiHeadCritic(num_heads, **kwargs)``; apply returns ``[..., K]`` normalised values."""
    return make_network(MultiHeadCritic(num_heads=num_heads, **kwargs), obs_size)


def make_discriminator_network(obs_size: int, num_heads: int = 32, **kwargs: Any) -> Network:
    """``DiscriminatorEnsemble(num_heads, **kwargs)``; apply returns ``[..., num_heads]``.

    ``head_grad_sq_norms`` is ``head_input_grad_sq_norms`` with the module's activation.
    """
    module = DiscriminatorEnsemble(num_heads=num_heads, **kwargs)
    net = make_network(module, obs_size)
    return dataclasses.replace(
        net, head_grad_sq_norms=lambda params, x: head_input_grad_sq_norms(params, x, module.activation)
    )


def value_head(params: Params) -> tuple[jax.Array, jax.Array]:
    """``(kernel [H, K], bias [K])`` of a ``MultiHeadCritic``'s last layer."""
    layer = params["params"][VALUE_HEAD]
    return layer["kernel"], layer["bias"]


def replace_value_head(params: Params, kernel: jax.Array, bias: jax.Array) -> Params:
    """Copy of critic ``params`` with the value head replaced (e.g. after PopArt rescaling)."""
    inner = dict(params["params"])
    inner[VALUE_HEAD] = {**inner[VALUE_HEAD], "kernel": kernel, "bias": bias}
    return {**params, "params": inner}
