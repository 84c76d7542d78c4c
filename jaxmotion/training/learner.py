"""The learner: rollout, discriminator update, rewards, GAE, PopArt, PPO.

One iteration (``Learner.iteration``) is a pure function of a ``TrainState``;
``loop.make_train_chunk`` scans ``K`` of them under one ``jax.jit`` with the state donated and
the environment batch sharded over a ``data`` mesh axis (synchronous data parallelism, as in
DD-PPO). Over several devices the iteration runs per device under ``shard_map`` (``axis``): each
device steps, scores and trains on its own environments and minibatch shares, and every batch
statistic (observation and discriminator normalisers, PopArt, advantage standardisation), every
gradient and every logged mean is reduced over the axis, so the parameters stay replicated.

Objectives: one per body-group discriminator and one per reward the task names
(``env.task.reward_names``), each with its own critic head, GAE and PopArt normaliser; advantages
are standardised per objective and combined with weights ω (Σω = 1, ``tasks.combine_weights``)
into one PPO surrogate. The observation's body-state part is normalised, the goal part is not.
``multi_objective=False`` sums the rewards into one objective with one critic head;
``popart=False`` trains the critic on raw returns. The policy is an object of ``nets/policies.py``
(a Gaussian MLP, a mixture of experts, or one built on a frozen part: the incremental policy, a
composer of primitives); the learner only asks it for its distribution and, for a recurrent one,
carries its state through the rollout.
"""

from __future__ import annotations

from typing import Any

import jax
import jax.numpy as jnp
import numpy as np
import optax
from flax import struct
from jax.sharding import Mesh, PartitionSpec as P

from jaxmotion.algos import disc as D
from jaxmotion.algos import gae as G
from jaxmotion.algos import normalizer as N
from jaxmotion.algos import popart as PA
from jaxmotion.algos import ppo as PPO
from jaxmotion.config.checks import check_fits, report, validate
from jaxmotion.config.errors import ConfigError
from jaxmotion.envs.bout import env_bytes, make_env
from jaxmotion.envs.humanoid import EnvConfig, EnvState, HumanoidEnv  # noqa: F401  (re-exported)
from jaxmotion.training.hparams import DiscConfig, NetConfig, PPOConfig, Scene, TrainConfig  # noqa: F401  (re-exported)
from jaxmotion.nets import networks as nets
from jaxmotion.nets.moe import decoder_learns
from jaxmotion.nets.policies import PolicyState, make_policy, no_carry
from jaxmotion.training.pool import OpponentPool
from jaxmotion.tasks import combine_weights


@struct.dataclass
class TrainState:
    """Everything the loop carries; a pytree, checkpointed whole."""

    env_state: EnvState
    obs: jax.Array
    policy_params: Any
    critic_params: Any
    disc_params: tuple
    opt_state: Any
    disc_opt_state: tuple
    obs_norm: N.NormalizerState
    disc_norm: tuple
    popart: PA.PopArtState
    rng: jax.Array
    iteration: jax.Array
    meta: Any = None
    """The frozen meta policy's ``PolicyState`` (incremental learning), else None."""
    clip_fails: Any = None
    """Hard-negative mining: cumulative failures [C] of every tracked clip, else None."""
    clip_weights: Any = None
    """Hard-negative mining: the reset's clip probabilities [C] (``init_lib.clip_weight`` scaled), else None."""
    pool: Any = None
    """Self-play's opponent pool (``pool.PoolState``), else None."""
    policy_carry: Any = None
    """A recurrent policy's state per environment ([B, (P,) C], ``Policy.carry_size``), else None."""


AGENT_FIELDS = ("policy_params", "critic_params", "opt_state", "obs_norm", "popart")
"""The ``TrainState`` fields that belong to one acting agent; with ``player_policies='separate'``
each has a leading player axis."""


def agent_of(ts: TrainState, player: int) -> TrainState:
    """``ts`` with one player's agent (``player_policies='separate'``), as a shared-policy state."""
    return ts.replace(**{f: jax.tree.map(lambda x: x[player], getattr(ts, f)) for f in AGENT_FIELDS})


@struct.dataclass
class Transition:
    """One control step of the rollout, for every environment ([T, B, ...] after the scan)."""

    obs: jax.Array
    action: jax.Array
    log_prob: jax.Array
    extra: jax.Array  # [.., X] what the policy conditioned on besides obs (``Policy.extra``; a meta action)
    final_obs: jax.Array
    disc_obs: tuple
    terminated: jax.Array
    truncated: jax.Array
    unstable: jax.Array
    task_reward: jax.Array
    info: dict


class Learner:
    """Static pieces of a run (env, networks, optimisers) and its pure update functions."""

    def __init__(self, cfg: TrainConfig, env: HumanoidEnv | None = None, meta=None):
        """``meta``: the frozen part the policy builds on (``training.meta.Meta`` that ``cfg.meta``
        names, or ``training.primitives.Primitives`` of ``cfg.primitives``);
        ``training.runs.make_learner`` loads it. Every setting is checked (``config.checks``)
        before anything is built: the rules between them against ``env`` where one is given."""
        self.cfg = validate(cfg, rules=env is None)
        if bool(cfg.meta or cfg.primitives) != (meta is not None):
            raise ConfigError("a learner with a meta policy or primitives is built by training.runs.make_learner")
        self.env = env if env is not None else make_env(cfg.env)
        self.players = getattr(self.env, "players", 1)
        """Players per environment: each is a sample of its own (one shared policy, self-play)."""
        report(cfg, cfg.rules(Scene.of_env(self.env, cfg.env)))
        check_fits("ppo.num_envs", cfg.ppo.num_envs, env_bytes(self.env, cfg.ppo.horizon), "the environments")
        self.separate = cfg.player_policies == "separate"
        """One policy (and critic, normaliser, PopArt, optimiser) per player: the agent's state has
        a leading player axis (``AGENT_FIELDS``)."""
        self.pool = (
            OpponentPool(cfg.opponent_pool, cfg.opponent_share, cfg.opponent_every, cfg.ppo.num_envs, self.players)
            if cfg.opponent_pool > 0
            else None
        )
        task = self.env.task
        self.objective_names = tuple(g.name for g in cfg.env.groups) + tuple(task.reward_names)
        n_obj = len(self.objective_names)
        self.num_objectives = n_obj if cfg.ppo.multi_objective else 1
        if cfg.ppo.objective_weights:  # their number and signs: TrainConfig.rules
            w = np.asarray(cfg.ppo.objective_weights, np.float64)
        else:
            try:
                w = combine_weights(tuple(g.weight for g in cfg.env.groups), task.weights())
            except ValueError as e:
                raise ConfigError(f"env.groups and env.task weights: {e}") from None
        self.reward_weights = jnp.asarray(w / w.sum(), jnp.float32)
        self.body_obs_size = self.env.body_obs_size
        self.norm_size = self.env.obs_size if cfg.ppo.normalize_goal else self.body_obs_size
        """The leading observation features the running statistics normalise (``ppo.normalize_goal``)."""
        self.objective_weights = self.reward_weights if cfg.ppo.multi_objective else jnp.ones((1,), jnp.float32)
        nc = cfg.net
        self.meta = meta
        # A frozen part (a meta policy, primitives) makes the policy that builds on it.
        self.policy = meta.make_policy(self.env, nc) if meta is not None else make_policy(self.env, nc)
        self.critic = nets.make_critic_network(
            self.env.obs_size,
            self.num_objectives,
            hidden_sizes=nc.critic_hidden,
            activation=nc.activation,
            hidden_init_scale=nc.critic_hidden_init,
        )
        self.discs = tuple(
            nets.make_discriminator_network(
                d, nc.disc_heads, hidden_sizes=nc.disc_hidden, hidden_gain=nc.disc_hidden_gain
            )
            for d in self.env.disc_obs_sizes()
        )
        pc = cfg.ppo
        self.optimizer = PPO.make_optimizer(
            pc.max_grad_norm, pc.actor_lr, pc.critic_lr, pc.meta_weight_lr if self.policy.weight_size else 0.0
        )
        self.disc_optimizer = optax.adam(cfg.disc.lr)
        self.hard_negatives = cfg.hard_negatives_every > 0  # a task that mines clips: TrainConfig.rules
        # The configured loss's floor; the class attribute below is the default (hinge) one.
        self.MIN_REWARD = D.MIN_REWARD[cfg.disc.loss]

    # The lowest reward a discriminator objective can pay per step (``disc.disc_reward``) with
    # the default hinge loss; an instance has its ``cfg.disc.loss``'s (``disc.MIN_REWARD``).
    MIN_REWARD = D.MIN_REWARD["hinge"]

    # ---- init ----------------------------------------------------------------------------
    def init_agent(self, k_pol: jax.Array, k_crit: jax.Array) -> dict:
        """One agent's learnable state (the ``AGENT_FIELDS`` of a ``TrainState``)."""
        pp = self.policy.init(k_pol)
        cp = self.critic.init(k_crit)
        return dict(
            policy_params=pp,
            critic_params=cp,
            opt_state=self.optimizer.init({"actor": pp, "critic": cp}),
            obs_norm=N.normalizer_init(self.norm_size),
            popart=PA.popart_init(self.num_objectives),
        )

    def init(self, rng: jax.Array) -> TrainState:
        """A fresh TrainState (un-sharded; see ``loop.shard_state``), compiled once per learner
        (op by op, its few hundred operations are slower than compiling them)."""
        fn = self.__dict__.get("_init_fn")
        if fn is None:
            fn = self.__dict__["_init_fn"] = jax.jit(self._init)
        return fn(rng)

    def _init(self, rng: jax.Array) -> TrainState:
        k_env, k_pol, k_crit, k_disc, rng = jax.random.split(rng, 5)
        env_state, obs = jax.vmap(self.env.reset)(jax.random.split(k_env, self.cfg.ppo.num_envs))
        if self.separate:  # one agent per player, independently initialised
            agent = jax.vmap(self.init_agent)(
                jax.random.split(k_pol, self.players), jax.random.split(k_crit, self.players)
            )
        else:
            agent = self.init_agent(k_pol, k_crit)
        dps = tuple(d.init(k) for d, k in zip(self.discs, jax.random.split(k_disc, len(self.discs))))
        return TrainState(
            env_state=env_state,
            obs=obs,
            disc_params=dps,
            disc_opt_state=tuple(self.disc_optimizer.init(p) for p in dps),
            disc_norm=tuple(N.normalizer_init(d) for d in self.env.disc_obs_sizes()),
            rng=rng,
            iteration=jnp.zeros((), jnp.int32),
            **agent,
            meta=None if self.meta is None else self.meta.state,
            clip_fails=jnp.zeros((self.env.init_lib.num_clips,), jnp.int32) if self.hard_negatives else None,
            # A copy: the chunk donates the state, which must not delete the library's own array.
            clip_weights=jnp.array(self.env.init_lib.clip_weight, copy=True) if self.hard_negatives else None,
            pool=self.pool.init(agent["policy_params"], agent["obs_norm"]) if self.pool else None,
            policy_carry=self.initial_carry(obs) if self.policy.carry_size else None,
        )

    # ---- acting --------------------------------------------------------------------------
    def normalize_obs(self, norm: N.NormalizerState, obs: jax.Array) -> jax.Array:
        """The body-state features normalised (and clipped), the goal features after them raw
        (with ``ppo.normalize_goal``: normalised too)."""
        body = N.normalize(norm, obs[..., : self.norm_size], self.cfg.ppo.obs_clip)
        return jnp.concatenate([body, obs[..., self.norm_size :]], -1)

    def policy_weights(self, ts: TrainState | PolicyState, obs: jax.Array) -> jax.Array:
        """The policy's composition weights [B, W] at raw observations (``Policy.weights``: the
        incremental policy's w per DoF; [B, 0] for a plain policy)."""
        return self.policy.weights(ts.policy_params, self.normalize_obs(ts.obs_norm, obs))

    def act(
        self, ts: TrainState | PolicyState, obs: jax.Array, rng: jax.Array | None, carry: jax.Array | None = None
    ) -> tuple[jax.Array, jax.Array, jax.Array]:
        """Samples (``rng=None``: the mean) action [B, A], its log-prob [B] and the policy's
        ``extra`` (a meta action, the carried state; [B, 0] for a plain policy). ``carry``: a
        recurrent policy's state [B, C] (``initial_carry``, ``next_carry``, ``reset_carry``).
        With separate player policies, player p's policy acts on ``obs[..., p, :]``."""
        if carry is None:
            if self.policy.carry_size:
                raise ConfigError("this evaluation does not carry a recurrent policy's state (net.policy=moe)")
            carry = no_carry(obs)
        if not self.separate:
            return self._act(ts, obs, rng, carry)

        def one(policy_params, obs_norm, o, c, p):
            sub = PolicyState(policy_params=policy_params, obs_norm=obs_norm, meta=None)
            return self._act(sub, o, None if rng is None else jax.random.fold_in(rng, p), c)

        a, logp, extra = jax.vmap(one)(
            ts.policy_params, ts.obs_norm, *_players_first(obs, carry), jnp.arange(self.players)
        )
        return jnp.moveaxis(a, 0, -2), jnp.moveaxis(logp, 0, -1), jnp.moveaxis(extra, 0, -2)

    def initial_carry(self, obs: jax.Array) -> jax.Array:
        """A recurrent policy's state at an episode's start for observations ``obs``: zeros."""
        return jnp.zeros(obs.shape[:-1] + (self.policy.carry_size,), obs.dtype)

    def next_carry(self, ts: TrainState | PolicyState, obs: jax.Array, extra: jax.Array) -> jax.Array:
        """The state a recurrent policy carries to the next step, after acting on ``obs`` with
        ``extra`` (``act``'s third output)."""
        nxt = lambda pp, norm, o, e: self.policy.next_carry(pp, self.normalize_obs(norm, o), e)
        if not self.separate:
            return nxt(ts.policy_params, ts.obs_norm, obs, extra)
        out = jax.vmap(nxt)(ts.policy_params, ts.obs_norm, *_players_first(obs, extra))
        return jnp.moveaxis(out, 0, -2)

    def reset_carry(self, carry: jax.Array, done: jax.Array) -> jax.Array:
        """``carry`` back to its start where an episode ended (``done`` [B], or [B, P]: a bout
        restarts for both players when either is done)."""
        if self.players > 1:
            done = jnp.any(done, -1, keepdims=True)
        return jnp.where(done[..., None], jnp.zeros((), carry.dtype), carry)

    def _act(self, ts, obs, rng, carry=None):
        """``act`` for one agent (the shared policy, or one player's own)."""
        extra = self.policy.extra(ts.meta, obs, None if rng is None else jax.random.fold_in(rng, 1))
        extra = jnp.concatenate([extra, no_carry(obs) if carry is None else carry], -1)
        mean, log_std = self.policy.dist(ts.policy_params, self.normalize_obs(ts.obs_norm, obs), extra)
        if rng is None:
            return mean, jnp.zeros(mean.shape[:-1]), extra
        action = mean + jnp.exp(log_std) * jax.random.normal(rng, mean.shape)
        return action, PPO.gaussian_log_prob(mean, log_std, action), extra

    def batch_step(self, mesh: Mesh | None = None):
        """``vmap(env.step)``; over a mesh of several devices, each device steps its own shard
        (``shard_map``), which a host-callback physics backend needs to stay parallel."""
        step = jax.vmap(self.env.step)
        if mesh is None or mesh.size == 1:
            return step
        return jax.shard_map(
            step, mesh=mesh, in_specs=(P("data"), P("data"), P("data")), out_specs=P("data"), check_vma=False
        )

    def rollout(
        self, ts: TrainState, mesh: Mesh | None = None, axis: str | None = None
    ) -> tuple[TrainState, Transition]:
        """Unrolls the policy for ``horizon`` control steps in every environment: [T, B, ...]
        (two players with a shared policy: [T, B * P, ...]; separate policies: [T, B, P, ...]).

        Each environment gets one fresh reset state per rollout, made before the scan, instead of
        a reset computed (and mostly thrown away) on every step: on the 2-core CPU that reset was
        half the cost of a rollout. An environment that ends two episodes within one rollout
        (``horizon`` = 8 steps, 0.27 s) starts both from that same reference state.

        ``axis``: called per device inside ``shard_map`` (``ts`` holds this device's environments
        and a per-device ``rng``; see ``iteration``).
        """
        batch_step = self.batch_step(mesh) if axis is None else jax.vmap(self.env.step)
        rng, key, k_pool = jax.random.split(ts.rng, 3)
        pool = jax.vmap(self.env.reset, in_axes=(0, None))(jax.random.split(k_pool, ts.obs.shape[0]), ts.clip_weights)

        def step(carry, key):
            env_state, obs, opp, pc = carry
            action, logp, extra = self.act(ts, obs, key, pc)
            pc = self.next_carry(ts, obs, extra)
            if self.pool is not None:  # player 1 of the pool bouts: an earlier self
                action = self.pool.act(self._act, opp, ts.meta, obs, action, jax.random.fold_in(key, 2))
            env_state, out = batch_step(env_state, action, pool)
            pc = self.reset_carry(pc, out.terminated | out.truncated)
            if self.pool is not None:
                opp = self.pool.redraw(opp, jnp.any(out.terminated | out.truncated, -1), jax.random.fold_in(key, 3))
            tr = Transition(
                obs=obs,
                action=action,
                log_prob=logp,
                extra=extra,
                final_obs=out.final_obs,
                disc_obs=out.disc_obs,
                terminated=out.terminated,
                truncated=out.truncated,
                unstable=out.unstable,
                task_reward=out.task_reward,
                info=out.info,
            )
            return (env_state, out.obs, opp, pc), tr

        keys = jax.random.split(key, self.cfg.ppo.horizon)
        pc0 = no_carry(ts.obs) if ts.policy_carry is None else ts.policy_carry
        (env_state, obs, opp, pc), traj = jax.lax.scan(step, (ts.env_state, ts.obs, ts.pool, pc0), keys)
        if self.players > 1 and not self.separate:  # every player is a sample of the shared policy
            traj = players_as_samples(traj)
        pc = None if ts.policy_carry is None else pc
        return ts.replace(env_state=env_state, obs=obs, rng=rng, pool=opp, policy_carry=pc), traj

    # ---- discriminators --------------------------------------------------------------------
    def _update_disc(self, net, params, opt_state, norm, pol, ref, rng, axis=None):
        """One pass of minibatches over [n, D] policy and reference windows; returns new state.
        With ``axis`` each device takes its share of every minibatch and the gradients are averaged."""
        dc = self.cfg.disc
        norm = N.normalizer_update(norm, jnp.concatenate([pol, ref], 0), axis_name=axis)
        k_perm, k_gp = jax.random.split(rng)
        n = pol.shape[0]
        size = dc.minibatch_size // _devices(axis)
        nmb = n // size
        perm = jax.random.permutation(k_perm, n)[: nmb * size]
        mb = lambda x: N.normalize(norm, x[perm], None).reshape(nmb, size, -1)

        def body(carry, xs):
            p, o = carry
            x_pol, x_ref, k = xs
            (_, m), grads = jax.value_and_grad(D.disc_loss, argnums=1, has_aux=True)(
                net.apply, p, x_pol, x_ref, k, dc.gp_weight, dc.gp_mode, net.head_grad_sq_norms, dc.loss
            )
            updates, o = self.disc_optimizer.update(_mean(grads, axis), o, p)
            return (optax.apply_updates(p, updates), o), m

        (params, opt_state), metrics = jax.lax.scan(
            body, (params, opt_state), (mb(pol), mb(ref), jax.random.split(k_gp, nmb))
        )
        return params, opt_state, norm, jax.tree.map(jnp.mean, metrics)

    def group_rewards(self, ts: TrainState, traj: Transition) -> jax.Array:
        """Discriminator reward of every group for a rollout, without updating: [T, B, G]."""
        T, B = traj.terminated.shape
        out = []
        for g, net in enumerate(self.discs):
            x = N.normalize(ts.disc_norm[g], traj.disc_obs[g].reshape(T * B, -1), None)
            logits = net.apply(ts.disc_params[g], x)
            out.append(D.disc_reward(logits, self.cfg.disc.loss).reshape(T, B))
        return jnp.stack(out, -1) if out else jnp.zeros((T, B, 0), jnp.float32)

    def disc_step(self, ts: TrainState, traj: Transition, axis: str | None = None):
        """Updates every ensemble on this rollout vs fresh reference windows; returns rewards [T,B,G]."""
        T, B = traj.terminated.shape
        rng, k_ref, k_upd = jax.random.split(ts.rng, 3)
        refs = self.env.ref_disc_obs(k_ref, T * B)
        new_p, new_o, new_n, metrics = [], [], [], {}
        for g, (net, key) in enumerate(zip(self.discs, jax.random.split(k_upd, len(self.discs)))):
            pol = traj.disc_obs[g].reshape(T * B, -1)
            p, o, n, m = self._update_disc(
                net, ts.disc_params[g], ts.disc_opt_state[g], ts.disc_norm[g], pol, refs[g], key, axis
            )
            new_p.append(p)
            new_o.append(o)
            new_n.append(n)
            metrics.update({f"disc/{self.cfg.env.groups[g].name}/{k}": v for k, v in m.items()})
        ts = ts.replace(disc_params=tuple(new_p), disc_opt_state=tuple(new_o), disc_norm=tuple(new_n), rng=rng)
        # Rewards come from the updated discriminators, on the same windows (as the authors' code).
        rewards = self.group_rewards(ts, traj)
        for g, gc in enumerate(self.cfg.env.groups):
            metrics[f"reward/{gc.name}"] = jnp.mean(rewards[..., g])
        return ts, rewards, metrics

    # ---- PPO -----------------------------------------------------------------------------
    def values(self, ts: TrainState, obs: jax.Array) -> jax.Array:
        """Unnormalised values [..., K] of raw observations."""
        v = self.critic.apply(ts.critic_params, self.normalize_obs(ts.obs_norm, obs))
        return PA.denormalize(ts.popart, v) if self.cfg.ppo.popart else v

    def ppo_step(self, ts: TrainState, traj: Transition, rewards: jax.Array, axis: str | None = None):
        """GAE per objective, PopArt, then PPO epochs over minibatches (with ``axis``: each
        device's share of every minibatch, gradients averaged over the devices)."""
        pc = self.cfg.ppo
        if not pc.multi_objective:
            rewards = (rewards * self.reward_weights).sum(-1, keepdims=True)
        values = self.values(ts, traj.obs)
        rewards, next_values, term, trunc = G.apply_termination(
            rewards,
            self.values(ts, traj.final_obs),
            traj.terminated,
            traj.truncated,
            pc.terminate_reward,
            pc.gamma,
            pc.absorbing_termination,
        )
        adv, returns = G.compute_gae(rewards, values, next_values, term, trunc, pc.gamma, pc.lam)
        metrics = {}
        if pc.popart:
            new_pa = PA.popart_update(ts.popart, returns, pc.popart_beta, axis_name=axis)
            w, b = nets.value_head(ts.critic_params)
            w, b = PA.preserve_outputs(ts.popart, new_pa, w, b)
            ts = ts.replace(popart=new_pa, critic_params=nets.replace_value_head(ts.critic_params, w, b))
            metrics["popart/mean"] = new_pa.mean
            metrics["popart/std"] = PA.std(new_pa)
        n = rewards.shape[0] * rewards.shape[1]
        flat = lambda x: x.reshape((n,) + x.shape[2:])
        _, std_adv = PPO.combine_advantages(flat(adv), self.objective_weights, axis_name=axis)
        nobs = self.normalize_obs(ts.obs_norm, flat(traj.obs))
        # The policy also sees what it conditioned on when acting (a [N, 0] array for a plain policy).
        batch = PPO.PPOBatch(
            obs={"x": nobs, "extra": flat(traj.extra)},
            actions=flat(traj.action),
            log_probs=flat(traj.log_prob),
            advantages=std_adv,
            returns=flat(returns),
        )
        popart_state = ts.popart if pc.popart else None
        policy_apply = lambda p, o: self.policy.dist(p, o["x"], o["extra"])
        critic_apply = lambda p, o: self.critic.apply(p, o["x"])

        def loss_fn(params, mb):
            return PPO.ppo_losses(
                params["actor"],
                params["critic"],
                mb,
                policy_apply,
                critic_apply,
                self.objective_weights,
                popart_state,
                pc.clip_eps,
                pc.value_coef,
                pc.entropy_coef,
                pc.per_objective_clip,
            )

        size = pc.minibatch_size // _devices(axis)
        nmb = n // size
        frozen = self.frozen_mask(ts)

        def sgd_step(carry, mb):
            params, opt_state = carry
            (_, m), grads = jax.value_and_grad(loss_fn, has_aux=True)(params, mb)
            grads = _zero(_mean(grads, axis), frozen)
            updates, opt_state = self.optimizer.update(grads, opt_state, params)
            return (optax.apply_updates(params, _zero(updates, frozen)), opt_state), m

        def epoch(carry, key):
            perm = jax.random.permutation(key, n)[: nmb * size]  # all of it, but with a pool
            mbs = jax.tree.map(lambda x: x[perm].reshape((nmb, size) + x.shape[1:]), batch)
            return jax.lax.scan(sgd_step, carry, mbs)

        rng, key = jax.random.split(ts.rng)
        params = {"actor": ts.policy_params, "critic": ts.critic_params}
        (params, opt_state), m = jax.lax.scan(epoch, (params, ts.opt_state), jax.random.split(key, pc.epochs))
        metrics.update({f"ppo/{k}": jnp.mean(v) for k, v in m.items()})
        for k in range(rewards.shape[-1]):
            metrics[f"return/{k}"] = jnp.mean(returns[..., k])
        ts = ts.replace(policy_params=params["actor"], critic_params=params["critic"], opt_state=opt_state, rng=rng)
        return ts, metrics

    def frozen_mask(self, ts: TrainState) -> Any:
        """Booleans over ``{"actor", "critic"}``: the parameters this iteration leaves as they are (a
        mixture's decoder in its encoder-only turns, ``nets.moe.decoder_learns``); None: none."""
        cfg = self.cfg
        if not (cfg.decoder_start or cfg.decoder_every):
            return None
        frozen = ~decoder_learns(ts.iteration, cfg.decoder_start, cfg.decoder_every)
        actor = jax.tree.map(lambda d: frozen & d, self.policy.decoder_mask(ts.policy_params))
        return {"actor": actor, "critic": jax.tree.map(lambda _: jnp.bool_(False), ts.critic_params)}

    # ---- one iteration -------------------------------------------------------------------
    def ppo_step_players(self, ts: TrainState, traj: Transition, rewards: jax.Array, axis: str | None = None):
        """``ppo_step`` for every player's own agent on its own transitions ([T, B, P, ...])."""
        keys = jax.random.split(ts.rng, self.players + 1)
        agents = {f: getattr(ts, f) for f in AGENT_FIELDS}

        def one(agent, traj_p, rewards_p, key):
            sub, m = self.ppo_step(ts.replace(rng=key, **agent), traj_p, rewards_p, axis)
            return {f: getattr(sub, f) for f in AGENT_FIELDS}, m

        agents, m = jax.vmap(one, in_axes=(0, 2, 2, 0))(agents, traj, rewards, keys[1:])
        return ts.replace(rng=keys[0], **agents), jax.tree.map(lambda x: jnp.mean(x, 0), m)

    def update_obs_norm(self, norm: N.NormalizerState, traj: Transition, axis: str | None = None) -> N.NormalizerState:
        """The observation statistics moved by a rollout's valid (not unstable) observations."""

        def upd(norm, obs, unstable):
            body = obs[..., : self.norm_size]
            return N.normalizer_update(norm, body.reshape(-1, body.shape[-1]), ~unstable.reshape(-1), axis_name=axis)

        if self.separate:
            return jax.vmap(upd, in_axes=(0, 2, 2))(norm, traj.obs, traj.unstable)
        return upd(norm, traj.obs, traj.unstable)

    def iteration(self, ts: TrainState, mesh: Mesh | None = None, axis: str | None = None) -> tuple[TrainState, dict]:
        """One iteration over the whole batch (``mesh``: the batch's devices, physics stepped per
        shard), or, with ``axis``, this device's part of it inside ``shard_map``: the randomness of
        sampling, resets, reference windows and minibatches is drawn per device (the state's
        ``rng`` folded with the device's index), the carried ``rng`` stays replicated."""
        carried = None
        if axis is not None:
            carried, rng = jax.random.split(ts.rng)
            ts = ts.replace(rng=jax.random.fold_in(rng, jax.lax.axis_index(axis)))
        ts, traj = self.rollout(ts, mesh, axis)
        pool_metrics = {}
        if self.pool is not None:
            pool_metrics = self.pool.metrics(traj, self.env.task.reward_names, ts.pool)
            traj = self.pool.learner_samples(traj)
        flat = players_as_samples(traj) if self.separate else traj
        ts, rewards, metrics = self.disc_step(ts, flat, axis)
        metrics.update(pool_metrics)
        rewards = jnp.concatenate([rewards, flat.task_reward], -1)
        for name, r in zip(self.env.task.reward_names, jnp.moveaxis(flat.task_reward, -1, 0)):
            metrics[f"reward/{name}"] = jnp.mean(r)
        for k, v in flat.info.items():
            metrics[f"task/{k}"] = jnp.mean(v.astype(jnp.float32))
        if self.separate:
            T, B = traj.terminated.shape[:2]
            ts, m = self.ppo_step_players(ts, traj, rewards.reshape((T, B, self.players) + rewards.shape[2:]), axis)
        else:
            ts, m = self.ppo_step(ts, traj, rewards, axis)
        metrics.update(m)
        # Observation statistics move after the update, so the update saw the rollout's own.
        obs_norm = self.update_obs_norm(ts.obs_norm, traj, axis)
        traj = flat
        done = traj.terminated | traj.truncated
        metrics["env/terminated"] = jnp.mean(traj.terminated)
        metrics["env/unstable"] = jnp.mean(traj.unstable)
        metrics["env/episodes_done"] = jnp.sum(done)
        if self.pool is not None:
            ts = ts.replace(pool=self.pool.snapshot(ts.pool, ts.policy_params, obs_norm, ts.iteration + 1))
        if axis is not None:
            metrics = {k: (jax.lax.psum if k in SUMMED else jax.lax.pmean)(v, axis) for k, v in metrics.items()}
            ts = ts.replace(rng=carried)
        return ts.replace(obs_norm=obs_norm, iteration=ts.iteration + 1), metrics


SUMMED = ("env/episodes_done",)
"""Logged metrics that are totals over the batch (the others are means)."""


def _zero(tree: Any, mask: Any) -> Any:
    """``tree`` with zeros where ``mask`` (a tree of booleans, or None: nowhere) is True."""
    if mask is None:
        return tree
    return jax.tree.map(lambda x, m: jnp.where(m, jnp.zeros((), x.dtype), x), tree, mask)


def _players_first(*xs: jax.Array) -> list[jax.Array]:
    """[..., P, D] arrays with the player axis moved first (to vmap over separate policies)."""
    return [jnp.moveaxis(x, -2, 0) for x in xs]


def _devices(axis: str | None) -> int:
    """Devices along ``axis`` (1 without one)."""
    return 1 if axis is None else jax.lax.axis_size(axis)


def _mean(tree: Any, axis: str | None) -> Any:
    """``tree`` averaged over the devices along ``axis`` (itself without one)."""
    return tree if axis is None else jax.lax.pmean(tree, axis)


def players_as_samples(traj: Transition) -> Transition:
    """[T, B, P, ...] -> [T, B * P, ...]: every player of every environment a sample."""
    return jax.tree.map(lambda x: x.reshape((x.shape[0], x.shape[1] * x.shape[2]) + x.shape[3:]), traj)
