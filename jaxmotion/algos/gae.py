"""Generalised advantage estimation (Schulman et al. 2016) with one estimate per objective.

Every objective ``k`` (each discriminator, each goal task) has its own reward stream and its own
critic head, so GAE runs independently per objective: the trailing ``[K]`` axis of rewards and
values is carried through unchanged. Episode ends are shared by all objectives.

Episode-end semantics, for step ``t`` (transition ``s_t -a_t-> s_{t+1}``):

* ``termination_t = 1`` (fall, failure): ``s_{t+1}`` is absorbing, its value is 0, so
  ``delta_t = r_t - V(s_t)``; the trace is cut.
* ``truncation_t = 1`` (time limit): the episode was stopped, not ended, so the target still
  bootstraps from the value of the *true* next state, ``delta_t = r_t + gamma V(s_{t+1}) - V(s_t)``,
  but the trace is cut because step ``t + 1`` of the rollout belongs to a new episode.
  ``V(s_{t+1})`` must be evaluated on the real next observation, before the env auto-resets; pass
  it in ``next_values``.
* If both flags are set, termination wins (no bootstrap).

So, with ``done_t = termination_t or truncation_t``::

    delta_t = r_t + gamma * (1 - termination_t) * next_values_t - values_t
    A_t     = delta_t + gamma * lam * (1 - done_t) * A_{t+1},      A_T = 0
    R_t     = A_t + values_t                                        (the critic's target)

Values here are in the unnormalised (return) space; PopArt callers denormalise first.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp


def next_values_from_bootstrap(values: jax.Array, bootstrap_value: jax.Array) -> jax.Array:
    """Builds ``next_values`` by shifting ``values`` one step and appending the bootstrap value.

    Only correct for steps that are not truncated: after a truncation ``values[t + 1]`` is the
    value of the reset state, not of the true next state. Use it when truncation is not
    used (or is folded into termination), or when the true next values are unavailable.

    Args:
      values: ``[T, B, ...]`` V(s_t) for each rollout step.
      bootstrap_value: ``[B, ...]`` V(s_T), the value of the observation after the last step.

    Returns:
      ``[T, B, ...]`` with ``next_values[t] = values[t + 1]`` and ``next_values[T - 1] =
      bootstrap_value``.
    """
    return jnp.concatenate([values[1:], bootstrap_value[None]], axis=0)


def _expand_flags(flags: jax.Array, like: jax.Array) -> jax.Array:
    """``[T, B]`` flags -> float broadcastable against ``like`` ``[T, B, ...]``."""
    flags = flags.astype(like.dtype)
    return flags.reshape(flags.shape + (1,) * (like.ndim - flags.ndim))


def compute_gae(
    rewards: jax.Array,
    values: jax.Array,
    next_values: jax.Array,
    terminations: jax.Array,
    truncations: jax.Array | None = None,
    gamma: float = 0.95,
    lam: float = 0.95,
) -> tuple[jax.Array, jax.Array]:
    """Per-objective GAE by a reverse ``lax.scan`` over time (see the module docstring).

    Args:
      rewards: ``[T, B, K]`` (or ``[T, B]``) reward of each objective.
      values: ``[T, B, K]`` V(s_t), unnormalised.
      next_values: either ``[T, B, K]`` V(s_{t+1}) evaluated on the true next observation
        (before any auto-reset), or ``[B, K]`` the bootstrap value V(s_T) of the observation after
        the last step, in which case ``next_values_from_bootstrap`` builds the rest (exact only
        for steps without truncation).
      terminations: ``[T, B]`` 1 where ``s_{t+1}`` is terminal (no bootstrap).
      truncations: ``[T, B]`` 1 where the episode was cut by a time limit after step ``t``
        (bootstrap, cut trace). ``None`` means no truncations.
      gamma: discount.
      lam: GAE lambda.

    Returns:
      ``(advantages, returns)``, both ``[T, B, K]``; ``returns = advantages + values``. Both are
      wrapped in ``stop_gradient``.
    """
    if next_values.ndim == values.ndim - 1:
        next_values = next_values_from_bootstrap(values, next_values)
    if truncations is None:
        truncations = jnp.zeros_like(terminations)
    term = _expand_flags(terminations, values)
    done = jnp.maximum(term, _expand_flags(truncations, values))

    deltas = rewards + gamma * (1.0 - term) * next_values - values
    trace_decay = gamma * lam * (1.0 - done)

    def step(carry, xs):
        delta, decay = xs
        adv = delta + decay * carry
        return adv, adv

    init = jnp.zeros_like(values[0])
    _, advantages = jax.lax.scan(step, init, (deltas, trace_decay), reverse=True)
    returns = advantages + values
    return jax.lax.stop_gradient(advantages), jax.lax.stop_gradient(returns)


def apply_termination(
    rewards: jax.Array,
    next_values: jax.Array,
    terminated: jax.Array,
    truncated: jax.Array,
    terminate_reward: float,
    gamma: float,
    absorbing: bool,
) -> tuple[jax.Array, jax.Array, jax.Array, jax.Array]:
    """How a terminating step (a fall) enters GAE; returns (rewards, next_values, term, trunc).

    Every objective is paid ``terminate_reward`` on the terminating step (None: its own rewards).
    With ``absorbing``, the fall leads to an absorbing state that keeps paying it, so its value
    ``terminate_reward / (1 - gamma)`` is bootstrapped and the trace is cut there (passed on as a
    truncation); a ``terminate_reward`` below every reward the objectives can pay then makes a
    fall always lower the return. Without it (the authors' code), the value after the fall is 0.

    Args:
      rewards, next_values: ``[T, B, K]``. terminated, truncated: ``[T, B]`` bool.
    """
    if terminate_reward is not None:
        rewards = jnp.where(terminated[..., None], terminate_reward, rewards)
    term = terminated.astype(jnp.float32)
    trunc = truncated.astype(jnp.float32)
    if absorbing:
        next_values = jnp.where(terminated[..., None], terminate_reward / (1.0 - gamma), next_values)
        term, trunc = jnp.zeros_like(term), jnp.maximum(term, trunc)
    return rewards, next_values, term, trunc
