"""Incremental learning (Xu et al. 2023, §5, Eq. 10, Alg. 1): a new policy on a frozen meta policy.

The new policy (``nets.policies.IncrementalPolicy``) is
``pi(a | s, g, a_meta) = N(mu + w * stop_gradient(a_meta), sigma^2)``: ``a_meta`` is *sampled*
from the frozen meta policy on its own slice of the observation (the body state and those of its
goal blocks that the new task also has, found by name in ``Task.goal_parts``), and ``mu``,
``sigma`` and ``w`` (one weight per action DoF) are outputs of the new network. ``a_meta`` is
stored in the rollout, because the PPO ratio depends on it.

Choices the paper leaves open (notes §2): ``w`` is a sigmoid head whose bias starts at
``NetConfig.meta_weight_bias`` (3: w = 0.95) and whose weights start at U(+-1e-4); the ``mu``
head starts at U(+-1e-4) as well, so the new policy starts as (0.95 times) the meta policy.

``TrainConfig.meta`` names the meta run: a run folder, or an experiment's folder of runs (its
newest run with a checkpoint is taken). Its policy parameters and observation statistics are
copied into ``TrainState.meta`` when the run starts and checkpointed with it, so a resumed run
keeps the meta policy it started with even if the meta run trains on. A meta run may itself be
incremental (its own meta comes along).
"""

from __future__ import annotations

from pathlib import Path

import jax.numpy as jnp
import numpy as np

from jaxmotion.config.errors import JaxmotionError
from jaxmotion.nets.policies import IncrementalPolicy, PolicyState
from jaxmotion.training import checkpoint as ckpt


class MetaError(JaxmotionError, ValueError):
    """The meta policy cannot be used: its run is missing, or it drives or sees something else."""


def resolve_run(path: str | Path, setting: str = "meta") -> Path:
    """A run folder, or the newest run with a checkpoint in a folder of runs; a clear error naming
    ``setting`` otherwise."""
    p = Path(path)
    if (p / ckpt.CONFIG_FILE).exists():
        return p
    runs = sorted(
        d for d in p.glob("*/") if (d / ckpt.CONFIG_FILE).exists() and any((d / "checkpoints").glob("[0-9]*"))
    )
    if not runs:
        raise MetaError(
            f"{setting}={path}: neither a run folder (no {ckpt.CONFIG_FILE}) nor a folder of runs "
            f"with a checkpoint; train that run first (e.g. make train EXP=goal/location_walk)"
        )
    return runs[-1]


def goal_index(meta_parts: tuple[tuple[str, int], ...], parts: tuple[tuple[str, int], ...]) -> np.ndarray:
    """Indices into a goal laid out as ``parts`` that give a goal laid out as ``meta_parts``."""
    start, offsets = 0, {}
    for name, n in parts:
        offsets[name] = (start, n)
        start += n
    idx = []
    for name, n in meta_parts:
        if name not in offsets or offsets[name][1] != n:
            have = ", ".join(f"{k} ({v[1]})" for k, v in offsets.items()) or "none"
            raise MetaError(
                f"the meta policy observes goal block {name!r} ({n} features), which this "
                f"task does not have (its blocks: {have})"
            )
        idx.extend(range(offsets[name][0], offsets[name][0] + n))
    return np.asarray(idx, np.int32)


class Meta:
    """A frozen meta policy: its learner (network, normaliser layout, own meta) and where its
    observation lies in the new one."""

    def __init__(self, run_dir: Path, experiment: str, learner, ts, env):
        """``learner`` and ``ts``: the meta run loaded (``training.runs.make_learner`` does it);
        ``env``: the new task's environment, whose observation the meta policy reads a slice of."""
        self.run_dir, self.experiment, self.learner = Path(run_dir), experiment, learner
        menv = self.learner.env
        if menv.action_size != env.action_size or menv.character.num_bodies != env.character.num_bodies:
            raise MetaError(
                f"meta policy {self.run_dir} drives another character ({menv.action_size} DoF, "
                f"{menv.character.num_bodies} bodies; this one: {env.action_size}, "
                f"{env.character.num_bodies})"
            )
        if menv.body_obs_size != env.body_obs_size:
            raise MetaError(
                f"meta policy {self.run_dir} sees {menv.cfg.policy_frames} frames of body state, "
                f"this task {env.cfg.policy_frames}: set env.policy_frames alike"
            )
        gidx = goal_index(menv.task.goal_parts, env.task.goal_parts)
        self.obs_index = jnp.asarray(
            np.concatenate([np.arange(env.body_obs_size), env.body_obs_size + gidx]), jnp.int32
        )
        self.state = PolicyState(policy_params=ts.policy_params, obs_norm=ts.obs_norm, meta=ts.meta)
        self.iteration = int(ts.iteration)

    def make_policy(self, env, net_cfg) -> IncrementalPolicy:
        """The incremental policy over this meta policy for ``env`` (``NetConfig``)."""
        return IncrementalPolicy(
            env.obs_size,
            env.action_size,
            self.act,
            net_cfg.meta_weight_bias,
            hidden_sizes=net_cfg.policy_hidden,
            activation=net_cfg.activation,
            state_dependent_std=net_cfg.state_dependent_std,
            init_log_std=net_cfg.init_log_std,
        )

    def act(self, state: PolicyState, obs, rng):
        """Sampled (``rng`` None: mean) meta action [..., A] of the new task's raw observations."""
        return self.learner.act(state, obs[..., self.obs_index], rng)[0]
