"""An opponent pool for two-player self-play (Won et al. 2021 train latest against latest; a pool of
earlier selves is the usual guard against a policy that only beats its current self).

With ``TrainConfig.opponent_pool = K > 0`` the learner keeps K snapshots of the shared policy
(its parameters and observation statistics), taken every ``opponent_every`` iterations into a
ring (the oldest replaced once full; the untrained policy is the first). A fixed share of the
bouts, the first ``bouts`` environments of the batch (environments are exchangeable, so which ones
does not matter), have player 1 acted by a pool member, drawn uniformly among the snapshots taken
so far when the bout starts and kept until it ends. Player 0 of those bouts is the learner, as are
both players of every other bout; the pool's transitions are left out of every update (they are
not the learner's samples: their log-probabilities are another policy's).

Everything is a pytree in ``TrainState.pool``, updated inside the compiled loop, checkpointed with
the run; only ``shared`` player policies take a pool.
"""

from __future__ import annotations

from typing import Any
from collections.abc import Callable

import jax
import jax.numpy as jnp
import numpy as np
from flax import struct

from jaxmotion.nets.policies import PolicyState


@struct.dataclass
class PoolState:
    policy_params: Any
    """The snapshots' policy parameters, each leaf with a leading [K] axis."""
    obs_norm: Any
    """Their observation statistics, [K, ...]."""
    filled: jax.Array
    """[] int32: snapshots taken so far (at most K); members are drawn from the first ``filled``."""
    opponent: jax.Array
    """[bouts] int32: the member acting player 1 in each pool bout."""


class OpponentPool:
    """The static side of the pool: its size, its bouts and the learner's sample indices."""

    def __init__(self, size: int, share: float, every: int, num_envs: int, players: int):
        if players != 2:
            raise ValueError(f"opponent_pool needs a two-player scene (env.players=2), got {players} player(s)")
        if every < 1:
            raise ValueError(f"opponent_every must be at least 1, got {every}")
        bouts = int(round(share * num_envs))
        if not 1 <= bouts < num_envs:
            raise ValueError(
                f"opponent_share {share} of {num_envs} bouts gives {bouts} pool bouts; "
                f"it must give at least one and leave at least one latest-vs-latest bout"
            )
        self.size, self.every, self.bouts, self.players = size, every, bouts, players
        b = np.arange(num_envs * players)
        pool_played = (b // players < bouts) & (b % players == 1)
        self.learner_index = np.flatnonzero(~pool_played)
        """Indices into the [B * P] sample axis (``players_as_samples``) that the learner played."""
        self.num_learner_samples = len(self.learner_index)

    def init(self, policy_params, obs_norm) -> PoolState:
        """A pool whose one snapshot (repeated K times) is the untrained policy."""
        stack = lambda x: jnp.broadcast_to(x, (self.size,) + jnp.shape(x)).copy()
        return PoolState(
            policy_params=jax.tree.map(stack, policy_params),
            obs_norm=jax.tree.map(stack, obs_norm),
            filled=jnp.ones((), jnp.int32),
            opponent=jnp.zeros((self.bouts,), jnp.int32),
        )

    def snapshot(self, pool: PoolState, policy_params, obs_norm, iteration: jax.Array) -> PoolState:
        """After ``iteration`` (counted from 1) iterations: every ``every`` of them the policy goes
        into the next slot of the ring (slot 0 holds the untrained policy until the ring wraps)."""
        n = iteration // self.every
        take = (iteration % self.every == 0) & (n > 0)
        slot = n % self.size
        put = lambda stack, x: jnp.where(
            take & (jnp.arange(self.size) == slot).reshape((-1,) + (1,) * jnp.ndim(x)), x[None], stack
        )
        return pool.replace(
            policy_params=jax.tree.map(put, pool.policy_params, policy_params),
            obs_norm=jax.tree.map(put, pool.obs_norm, obs_norm),
            filled=jnp.where(take, jnp.minimum(n + 1, self.size), pool.filled),
        )

    def redraw(self, pool: PoolState, done: jax.Array, rng: jax.Array) -> PoolState:
        """A new member for every pool bout that ended (``done`` [B]: any player's end)."""
        fresh = jax.random.randint(rng, (self.bouts,), 0, pool.filled)
        return pool.replace(opponent=jnp.where(done[: self.bouts], fresh, pool.opponent))

    def act(
        self, act_one: Callable, pool: PoolState, meta: Any, obs: jax.Array, action: jax.Array, rng: jax.Array | None
    ) -> jax.Array:
        """``action`` [B, P, A] with player 1 of the pool bouts acted by its pool member.
        ``act_one(policy_state, obs, rng)`` is the learner's one-agent act (sampling, or the mean
        when ``rng`` is None); every member acts on those observations and each bout keeps its own's."""
        o = obs[: self.bouts, 1]

        def member(params, norm, k):
            key = None if rng is None else jax.random.fold_in(rng, k)
            return act_one(PolicyState(policy_params=params, obs_norm=norm, meta=meta), o, key)[0]

        every = jax.vmap(member)(pool.policy_params, pool.obs_norm, jnp.arange(self.size))  # [K, n, A]
        mine = jnp.take_along_axis(every, pool.opponent[None, :, None], 0)[0]
        return action.at[: self.bouts, 1].set(mine)

    def learner_samples(self, tree):
        """[T, B * P, ...] -> [T, N, ...]: the samples the learner played."""
        return jax.tree.map(lambda x: jnp.take(x, self.learner_index, axis=1), tree)

    def metrics(self, traj, reward_names: tuple[str, ...], pool: PoolState) -> dict:
        """The learner's mean task rewards in the pool bouts (player 0 there), and the pool's size."""
        r = traj.task_reward[:, 0 : self.bouts * self.players : self.players]  # [T, n, R]
        m = {f"pool/{name}": jnp.mean(r[..., i]) for i, name in enumerate(reward_names)}
        m["pool/filled"] = pool.filled
        return m
