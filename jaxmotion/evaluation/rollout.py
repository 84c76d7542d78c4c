"""The rollout recorder: deterministic (or sampled) episodes of a learner's policy, every frame kept.

One compiled program per learner and shape (cached on the learner), returning numpy arrays that
the imitation metrics, the videos and the HTML replays all read.
"""

from __future__ import annotations

import jax
import jax.numpy as jnp
import numpy as np

from jaxmotion.training.learner import Learner, TrainState


def program(learner: Learner, kind: str, key, build):
    """The compiled program ``build()`` makes, once per learner, kind of evaluation and ``key``
    (shapes, clip set, opponent): evaluating several states (seeds, checkpoints, mining rounds) on
    one learner compiles once. The cache lives on the learner, so it goes when the learner does."""
    cache = learner.__dict__.setdefault("_programs", {})
    if (kind, key) not in cache:
        cache[(kind, key)] = build()
    return cache[(kind, key)]


def programs(learner: Learner, kind: str) -> int:
    """How many programs of ``kind`` the learner has compiled (``program``)."""
    return sum(k == kind for k, _ in learner.__dict__.get("_programs", {}))


def acting_policy(t: jax.Array, switch_steps: int, num_policies: int) -> jax.Array:
    """Index of the policy that chooses the action at control step ``t`` when ``num_policies``
    take turns every ``switch_steps`` steps (0: the first one always). One definition serves the
    choice of the action and its record, so what the video shows is what acted."""
    if not switch_steps:
        return jnp.zeros_like(t)
    return (t // switch_steps) % num_policies


def act(learner: Learner, ts, obs: jax.Array, rng: jax.Array | None, carry: jax.Array):
    """One step of ``learner``'s policy in an evaluation: (action, the carry to the next step)."""
    action, _, extra = learner.act(ts, obs, rng, carry)
    return action, learner.next_carry(ts, obs, extra)


def _rollout_fn(
    learner: Learner,
    episodes: int,
    steps: int,
    deterministic: bool,
    switch_steps: int = 0,
    actors: tuple[Learner, ...] = (),
):
    """The jitted rollout program ``(ts, key) -> arrays``, compiled once per learner and shape.

    ``ts`` may be a tuple of states whose policies take turns every ``switch_steps`` control
    steps (policy switching: only the acting parameters change, the env state carries on).
    ``actors`` are the learners whose networks act for those states, one each (default: all
    ``learner``): runs that share spaces may differ in networks, e.g. one with a meta policy."""
    sig = (episodes, steps, deterministic, switch_steps, tuple(id(a) for a in actors))
    return program(
        learner,
        "imitation",
        sig,
        lambda: _rollout_program(learner, episodes, steps, deterministic, switch_steps, actors),
    )


def _rollout_program(learner: Learner, episodes: int, steps: int, deterministic: bool, switch_steps: int, actors):
    env = learner.env
    actor = lambda i: actors[i] if actors else learner

    @jax.jit
    def run(ts, key):
        policies = ts if isinstance(ts, tuple) else (ts,)
        k_reset, k_act = jax.random.split(key)
        state, obs = jax.vmap(env.reset)(jax.random.split(k_reset, episodes))
        markers = lambda s: jax.vmap(env.task.markers)(s.goal, jax.tree.map(lambda x: x[:, -1], s.hist))

        def step(carry, xs):
            state, obs, alive, pcs = carry
            k, t = xs
            which = acting_policy(t, switch_steps, len(policies))
            acts, pcs = zip(
                *[act(actor(i), p, obs, None if deterministic else k, c) for i, (p, c) in enumerate(zip(policies, pcs))]
            )
            action = jnp.stack(acts)[which]
            # Incremental learning: the weights w of the meta action (paper Figs. 7-8).
            w = learner.policy_weights(policies[0], obs) if len(policies) == 1 else jnp.zeros((episodes, 0))
            state, out = jax.vmap(env.step)(state, action)
            done = out.terminated | out.truncated
            pcs = tuple(actor(i).reset_carry(c, done) for i, c in enumerate(pcs))
            # The recorded frame t + 1 is where step t + 1 begins: its acting policy is that step's.
            acting = jnp.full((episodes,), acting_policy(t + 1, switch_steps, len(policies)), jnp.int32)
            # A terminal frame is replaced by the auto-reset state, so it is dropped (masked).
            rec = (
                state.hist.pos[:, -1],
                state.hist.quat[:, -1],
                env.character_qpos(state.data.qpos),
                alive & ~done,
                alive & out.terminated,
                out.info,
                alive,
                out.task_reward,
                w,
                markers(state),
                acting,
            )
            return (state, out.obs, alive & ~done, pcs), rec

        alive0 = jnp.ones((episodes,), bool)
        pcs0 = tuple(actor(i).initial_carry(obs) for i in range(len(policies)))
        _, (pos, quat, qpos, alive, fell, info, stepped, task_reward, meta_w, mk, acting) = jax.lax.scan(
            step, (state, obs, alive0, pcs0), (jax.random.split(k_act, steps), jnp.arange(steps))
        )
        first = lambda x, xs: jnp.concatenate([x[None], xs], 0)
        acting0 = jnp.full((episodes,), acting_policy(jnp.int32(0), switch_steps, len(policies)), jnp.int32)
        return (
            first(state.hist.pos[:, -1], pos),
            first(state.hist.quat[:, -1], quat),
            first(env.character_qpos(state.data.qpos), qpos),
            first(alive0, alive),
            fell.any(0),
            info,
            stepped,
            task_reward,
            meta_w,
            jax.tree.map(first, markers(state), mk),
            first(acting0, acting),
        )

    return run


def rollout(
    learner: Learner,
    ts: TrainState | tuple[TrainState, ...],
    episodes: int,
    steps: int,
    seed: int = 0,
    deterministic: bool = True,
    switch_steps: int = 0,
    actors: tuple[Learner, ...] = (),
) -> dict[str, np.ndarray]:
    """Runs ``episodes`` environments for ``steps`` control steps with the policy's mean action.

    With a tuple of states and ``switch_steps`` > 0, their policies take turns every
    ``switch_steps`` steps on the same environments (they must share observation and action
    spaces; ``actors`` gives each its own learner); ``info`` then also holds ``switch`` [T, E],
    true at the first step of each turn.

    Returns numpy arrays: ``pos`` [T+1, E, nb, 3], ``quat`` [T+1, E, nb, 4] (world frame, the
    initial state first), ``qpos`` [T+1, E, nq] (MuJoCo generalised positions, for rendering),
    ``alive`` [T+1, E] (the episode has not ended yet), ``fell`` [E]; the task's per-step
    ``info`` {name: [T, E]}, ``stepped`` [T, E] (the step belongs to the episode, its last one
    included), ``task_reward`` [T, E, R] and, for an incremental policy, ``meta_w`` [T, E, A]
    (the weights of the meta action; [T, E, 0] otherwise), ``markers`` {name: [T+1, E, 2, 3]}:
    what the task draws of its goal (``Task.markers``) at each recorded state, and ``acting``
    [T+1, E] int: the index (in ``ts``) of the policy that chooses the action at each recorded
    state (the last: the one whose turn it would be; all zeros without switching).
    """
    run = _rollout_fn(
        learner,
        episodes,
        steps,
        deterministic,
        switch_steps if isinstance(ts, tuple) else 0,
        tuple(actors) if isinstance(ts, tuple) else (),
    )
    pos, quat, qpos, alive, fell, info, stepped, task_reward, meta_w, markers, acting = jax.device_get(
        run(ts, jax.random.PRNGKey(seed))
    )
    if isinstance(ts, tuple) and switch_steps:
        t = np.arange(steps)
        info = dict(info, switch=np.broadcast_to(((t % switch_steps) == 0) & (t > 0), (episodes, steps)).T)
    return {
        "pos": pos,
        "quat": quat,
        "qpos": qpos,
        "alive": alive,
        "fell": fell,
        "info": info,
        "stepped": stepped,
        "task_reward": task_reward,
        "meta_w": meta_w,
        "markers": markers,
        "acting": acting,
    }
