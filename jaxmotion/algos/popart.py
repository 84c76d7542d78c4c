"""PopArt return normalisation, one normaliser per critic head (van Hasselt et al. 2016).

Each critic head ``k`` predicts its value in a normalised space, ``v_k = (V_k - mu_k) / sigma_k``.
The statistics track the return targets of head ``k``; every time they move, the critic's last
linear layer is rescaled (``preserve_outputs``) so that the unnormalised output
``sigma_k * v_k + mu_k`` is exactly what it was before ("Preserving Outputs Precisely"), and
the value loss is a plain MSE in the normalised space ("Adaptively Rescaling Targets").

Statistics: exponential moving averages of the mean and the *centred* variance of the targets,
with step size ``beta`` (0.1 in the authors' code, one update per iteration from the batch of
returns), and Adam-style bias correction. The state stores the *bias-corrected* moments
directly, together with the correction weight ``debias = 1 - prod(1 - beta_i)``, so that
``normalize``, ``denormalize`` and ``preserve_outputs`` all use the same numbers and outputs are
preserved exactly from the very first update. (The authors' ``DiagonalPopArt`` corrects in the
forward pass but rescales with the uncorrected moments, so it preserves outputs only
approximately for the first ~50 updates; see shared/notes/compositemotion.md §0.7.)

Update rule, with the batch mean ``m1 = mean(x)`` and centred variance ``s1 = mean((x - m1)**2)``
over the ``N`` targets (the law of total variance for a mixture of the old statistics with
weight ``a = (1 - beta) * debias`` and the batch with weight ``beta``)::

    debias' = a + beta
    mean'   = (a * mean + beta * m1) / debias'
    var'    = (a * (var + (mean - mean')**2) + beta * (s1 + (m1 - mean')**2)) / debias'

so the first update (``debias = 0``) sets them to the batch's. ``sigma = max(sqrt(var), 1e-4)``.
The variance is never formed as ``E[x^2] - E[x]^2``: in float32, with returns near -20 and a
true std of 0.005, that difference reads 0.011 or drops to the floor (measured: a third of the
iterations), and each drop rescales the critic head by up to 200x.

Usage per iteration::

    old = state
    state = popart_update(state, returns.reshape(-1, K))
    w, b = preserve_outputs(old, state, w, b)      # critic value_head kernel [H, K], bias [K]
    targets = normalize(state, returns)            # for the value loss
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct

STD_MIN = 1e-4


@struct.dataclass
class PopArtState:
    """Bias-corrected running moments of the return targets of each critic head.

    Attributes:
      mean: ``[K]`` bias-corrected EMA of the targets.
      var: ``[K]`` bias-corrected EMA of the targets' variance (centred).
      debias: ``[]`` accumulated EMA weight ``1 - prod_i (1 - beta_i)``; 0 before any update.
      count: ``[]`` int32 number of updates.
    """

    mean: jax.Array
    var: jax.Array
    debias: jax.Array
    count: jax.Array


def popart_init(num_heads: int) -> PopArtState:
    """Identity normaliser (mean 0, std 1) for ``num_heads`` critic heads."""
    return PopArtState(
        mean=jnp.zeros((num_heads,), jnp.float32),
        var=jnp.ones((num_heads,), jnp.float32),
        debias=jnp.zeros((), jnp.float32),
        count=jnp.zeros((), jnp.int32),
    )


def popart_update(
    state: PopArtState, targets: jax.Array, beta: float = 0.1, axis_name: str | None = None
) -> PopArtState:
    """Moves the statistics towards the moments of a batch of return targets.

    Args:
      state: current statistics.
      targets: ``[..., K]`` unnormalised return targets (e.g. ``[T, B, K]`` or ``[N, K]``); all
        leading axes are pooled.
      beta: EMA step size in (0, 1].
      axis_name: inside ``shard_map``, the mesh axis the batch is split over (equal shares):
        the moments are those of every device's targets together.

    Returns:
      The new state. The critic's last layer must then be rescaled with ``preserve_outputs``.
    """
    targets = jax.lax.stop_gradient(targets).astype(jnp.float32)
    targets = targets.reshape(-1, targets.shape[-1])
    mean = (lambda x: jax.lax.pmean(x, axis_name)) if axis_name else (lambda x: x)
    m1 = mean(jnp.mean(targets, axis=0))
    s1 = mean(jnp.mean(jnp.square(targets - m1), axis=0))
    old_weight = (1.0 - beta) * state.debias
    debias = old_weight + beta
    mean = (old_weight * state.mean + beta * m1) / debias
    var = (old_weight * (state.var + jnp.square(state.mean - mean)) + beta * (s1 + jnp.square(m1 - mean))) / debias
    return PopArtState(
        mean=mean,
        var=var,
        debias=debias,
        count=state.count + 1,
    )


def std(state: PopArtState) -> jax.Array:
    """``[K]`` standard deviation of the targets, at least ``STD_MIN``."""
    return jnp.maximum(jnp.sqrt(jnp.maximum(state.var, 0.0)), STD_MIN)


def normalize(state: PopArtState, x: jax.Array) -> jax.Array:
    """``[..., K]`` unnormalised values/returns -> normalised space ``(x - mu) / sigma``."""
    return (x - state.mean) / std(state)


def denormalize(state: PopArtState, x: jax.Array) -> jax.Array:
    """``[..., K]`` normalised critic outputs -> unnormalised values ``sigma * x + mu``."""
    return x * std(state) + state.mean


def preserve_outputs(
    old_state: PopArtState, new_state: PopArtState, w: jax.Array, b: jax.Array
) -> tuple[jax.Array, jax.Array]:
    """Rescales the critic's last linear layer so unnormalised outputs are unchanged.

    With ``v = h @ w + b`` the normalised output of the last layer,
    ``sigma_new * (h @ w' + b') + mu_new == sigma_old * (h @ w + b) + mu_old`` for every ``h``.

    Args:
      old_state: statistics before ``popart_update``.
      new_state: statistics after it.
      w: ``[H, K]`` kernel of the value head (flax ``Dense`` layout).
      b: ``[K]`` bias of the value head.

    Returns:
      ``(w', b')`` with ``w' = w * sigma_old / sigma_new`` and
      ``b' = (sigma_old * b + mu_old - mu_new) / sigma_new``.
    """
    sigma_old, sigma_new = std(old_state), std(new_state)
    w_new = w * (sigma_old / sigma_new)
    b_new = (sigma_old * b + old_state.mean - new_state.mean) / sigma_new
    return w_new, b_new
