"""Frozen primitive policies for a composer (PHC §3.2; ``nets/composer.py``).

``TrainConfig.primitives`` names K run folders (or pretrained entries) of plain Gaussian policies
trained on the same character and observation (e.g. the stages of a progressive tracker). Their
policy parameters and observation statistics are stacked along a leading K axis and copied into
``TrainState.meta`` when the run starts, so they are checkpointed with it and a resumed run keeps
the primitives it started with; PPO's optimiser never sees them (they are not ``policy_params``),
and their outputs reach the composer only through the rollout's ``extra``.
"""

from __future__ import annotations

from pathlib import Path

import jax
import jax.numpy as jnp

from jaxmotion.config.errors import JaxmotionError
from jaxmotion.nets.composer import ComposerPolicy
from jaxmotion.nets.policies import PolicyState


class PrimitivesError(JaxmotionError, ValueError):
    """The primitives cannot be composed: another character or observation, another network, or a
    policy that is itself composed."""


def _shapes(tree) -> list:
    return [(jax.tree_util.keystr(p), tuple(x.shape)) for p, x in jax.tree_util.tree_flatten_with_path(tree)[0]]


class Primitives:
    """K frozen primitives: the learner of the first (all share its network) and their stacked
    state (``state``: a ``PolicyState`` whose leaves have a leading K axis)."""

    def __init__(self, loaded: list[tuple[Path, object, object]], env):
        """``loaded``: (run folder, learner, restored state) per primitive
        (``training.runs.load_run``); ``env``: the composer's environment."""
        if not loaded:
            raise PrimitivesError("primitives: name at least one run folder")
        self.run_dirs = tuple(Path(d) for d, _, _ in loaded)
        self.learner = loaded[0][1]
        for run_dir, learner, ts in loaded:
            penv = learner.env
            if penv.action_size != env.action_size or penv.obs_size != env.obs_size:
                raise PrimitivesError(
                    f"primitive {run_dir} drives {penv.action_size} DoF from {penv.obs_size} observations; "
                    f"this task: {env.action_size} from {env.obs_size} (train primitives on the same task layout)"
                )
            if learner.policy.extra_size or learner.separate:
                raise PrimitivesError(f"primitive {run_dir} is not a plain single-agent policy")
            if _shapes(ts.policy_params) != _shapes(loaded[0][2].policy_params):
                raise PrimitivesError(
                    f"primitive {run_dir} has another network than {self.run_dirs[0]} (net.policy_hidden alike)"
                )
        self.state = PolicyState(
            policy_params=jax.tree.map(lambda *x: jnp.stack(x), *[ts.policy_params for _, _, ts in loaded]),
            obs_norm=jax.tree.map(lambda *x: jnp.stack(x), *[ts.obs_norm for _, _, ts in loaded]),
        )
        self.iterations = tuple(int(ts.iteration) for _, _, ts in loaded)

    @property
    def k(self) -> int:
        return len(self.run_dirs)

    def dists(self, state: PolicyState, obs: jax.Array) -> tuple[jax.Array, jax.Array]:
        """The primitives' Gaussians at raw observations ``obs [..., D]``: (means, log_stds),
        each ``[..., K, A]``, every primitive with its own observation statistics."""
        lr = self.learner

        def one(params, norm):
            extra = jnp.zeros(obs.shape[:-1] + (0,), obs.dtype)
            return lr.policy.dist(params, lr.normalize_obs(norm, obs), extra)

        means, log_stds = jax.vmap(one)(state.policy_params, state.obs_norm)
        return jnp.moveaxis(means, 0, -2), jnp.moveaxis(log_stds, 0, -2)

    def make_policy(self, env, net_cfg) -> ComposerPolicy:
        """The composer over these primitives for ``env`` (``NetConfig``: rule, MLP, sigma)."""
        return ComposerPolicy(
            env.obs_size,
            env.action_size,
            self.k,
            self.dists,
            rule=net_cfg.composer,
            hidden_sizes=net_cfg.policy_hidden,
            activation=net_cfg.activation,
            init_log_std=net_cfg.init_log_std,
        )
