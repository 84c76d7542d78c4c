"""Running mean/variance observation normaliser, in the style of brax ``acme/running_statistics``.

The statistics are exact running moments over every sample seen so far, merged batch by batch
with Chan et al.'s parallel algorithm (numerically stable, unlike summing ``x`` and ``x**2``)::

    n      = n_a + n_b
    delta  = mean_b - mean_a
    mean   = mean_a + delta * n_b / n
    M2     = M2_a + M2_b + delta**2 * n_a * n_b / n,        var = M2 / n   (population variance)

Everything is float32, the count included: past ~1.7e7 samples the count is rounded, so
``n_b / n`` is accurate to float32 precision, which is harmless for a normaliser.

The policy state is normalised with ``clip=5.0``; each discriminator keeps its own, unclipped
statistics (``clip=None``), updated with both policy and reference observations.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
from flax import struct


@struct.dataclass
class NormalizerState:
    """Running statistics of a ``[D]`` feature vector.

    Attributes:
      count: ``[]`` float32 number of samples seen.
      mean: ``[D]`` running mean.
      summed_variance: ``[D]`` sum of squared deviations from the mean (Chan's ``M2``).
      std: ``[D]`` ``sqrt(summed_variance / count + var_eps)``, at most ``std_max``; 1 before
        any sample.
    """

    count: jax.Array
    mean: jax.Array
    summed_variance: jax.Array
    std: jax.Array


def normalizer_init(size: int) -> NormalizerState:
    """Empty statistics for ``size`` features (normalising is then the identity)."""
    return NormalizerState(
        count=jnp.zeros((), jnp.float32),
        mean=jnp.zeros((size,), jnp.float32),
        summed_variance=jnp.zeros((size,), jnp.float32),
        std=jnp.ones((size,), jnp.float32),
    )


def normalizer_update(
    state: NormalizerState,
    batch: jax.Array,
    mask: jax.Array | None = None,
    var_eps: float = 1e-5,
    std_max: float = 1e6,
    axis_name: str | None = None,
) -> NormalizerState:
    """Merges a batch into the running statistics.

    Args:
      state: current statistics.
      batch: ``[..., D]`` samples; all leading axes are pooled (e.g. ``[T, B, D]``).
      mask: ``[...]`` optional 0/1 weights of the samples (e.g. valid frames); masked samples are
        ignored. A batch with no valid sample leaves the statistics unchanged.
      var_eps: added to the variance before the square root (the authors' ``var + 1e-5``), so a
        feature that is constant up to float noise (the torso's offset in the pelvis frame) stays
        near zero instead of being blown up to unit scale: its std is at least ~3.2e-3.
      std_max: upper bound of the stored std.

    Returns:
      The new statistics.
    """
    batch = jax.lax.stop_gradient(batch).astype(jnp.float32)
    batch = batch.reshape(-1, batch.shape[-1])
    weights = jnp.ones((batch.shape[0],), jnp.float32) if mask is None else mask.astype(jnp.float32).reshape(-1)
    weights = weights[:, None]

    total = (lambda x: jax.lax.psum(x, axis_name)) if axis_name else (lambda x: x)
    n_b = total(jnp.sum(weights))
    safe_n_b = jnp.maximum(n_b, 1.0)
    mean_b = total(jnp.sum(weights * batch, axis=0)) / safe_n_b
    m2_b = total(jnp.sum(weights * jnp.square(batch - mean_b), axis=0))

    n = state.count + n_b
    safe_n = jnp.maximum(n, 1.0)
    delta = mean_b - state.mean
    mean = state.mean + delta * (n_b / safe_n)
    m2 = state.summed_variance + m2_b + jnp.square(delta) * (state.count * n_b / safe_n)

    std = jnp.minimum(jnp.sqrt(m2 / safe_n + var_eps), std_max)
    std = jnp.where(n > 0, std, state.std)
    return NormalizerState(count=n, mean=mean, summed_variance=m2, std=std)


def normalize(state: NormalizerState, x: jax.Array, clip: float | None = 5.0) -> jax.Array:
    """``[..., D]`` -> ``(x - mean) / std``, clipped to ``[-clip, clip]`` (no clip if None)."""
    y = (x - state.mean) / state.std
    if clip is not None:
        y = jnp.clip(y, -clip, clip)
    return y


def denormalize(state: NormalizerState, y: jax.Array) -> jax.Array:
    """Inverse of ``normalize`` (without the clip): ``[..., D]`` -> ``y * std + mean``."""
    return y * state.std + state.mean
