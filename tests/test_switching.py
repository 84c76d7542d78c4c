"""Policy switching (paper Fig. 9): policies that share observation and action spaces take turns
on the same environments; only the acting parameters change between two control steps."""

from __future__ import annotations

import jax
import numpy as np

from jaxmotion import eval as E
from jaxmotion.envs.humanoid import EnvConfig, GroupConfig, HumanoidEnv
from jaxmotion.motion import MotionLib, make_test_clip
from jaxmotion.tasks import TaskConfig
from jaxmotion.trainer import DiscConfig, Learner, NetConfig, PPOConfig, TrainConfig


def _learner() -> Learner:
    lib = MotionLib.from_clips([make_test_clip(30, 30.0, root_vel=(1.0, 0.0, 0.0), root_height=0.87)])
    env_cfg = EnvConfig(groups=(GroupConfig(name="full"),), episode_steps=20, policy_frames=2,
                        task=TaskConfig(name="location"))
    cfg = TrainConfig(env=env_cfg, net=NetConfig(policy_hidden=(8,), critic_hidden=(8,), disc_hidden=(8,),
                                                 disc_heads=2, init_log_std=0.0),
                      ppo=PPOConfig(num_envs=2, horizon=2, minibatch_size=4), disc=DiscConfig(minibatch_size=4))
    return Learner(cfg, env=HumanoidEnv(env_cfg, motion_libs=(lib,), init_lib=lib))


def test_switching_keeps_the_env_state_and_changes_only_the_policy():
    from conftest import jit_enabled
    learner = _learner()
    steps, every = 6, 2
    with jit_enabled():
        a, b = (learner.init(jax.random.PRNGKey(s)) for s in (0, 1))
        ro = E.rollout(learner, (a, b), episodes=2, steps=steps, switch_steps=every)
        # The same by hand on one env batch: A acts for 2 steps, then B for 2, then A again.
        reset, step = jax.jit(jax.vmap(learner.env.reset)), jax.jit(jax.vmap(learner.env.step))
        act = jax.jit(lambda p, o: learner.act(p, o, None)[0])
        state, obs = reset(jax.random.split(jax.random.split(jax.random.PRNGKey(0))[0], 2))
        qpos, acts = [np.asarray(state.data.qpos)], []
        for t in range(steps):
            action = act((a, b)[(t // every) % 2], obs)
            acts.append(np.asarray(action))
            state, out = step(state, action)
            obs = out.obs
            qpos.append(np.asarray(state.data.qpos))
        other = np.asarray(act(b, obs))
    np.testing.assert_allclose(ro["qpos"], np.stack(qpos), atol=1e-4)
    assert not np.allclose(acts[-1], other)  # the two policies do act differently
    np.testing.assert_array_equal(ro["info"]["switch"][:, 0], [False, False, True, False, True, False])
    m = E.switch_metrics(ro, learner.env.dt)
    # Switches are counted in episodes still running; both are at the first switch (t = 2).
    assert m["switches"] == int((ro["info"]["switch"] & ro["stepped"]).sum()) >= 2
    assert 0 <= m["falls_after_switch"] <= 2
