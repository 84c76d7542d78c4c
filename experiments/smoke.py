"""A few iterations of chest_open+squat at CPU size: checks the whole pipeline in under two
minutes (most of it compilation). Small networks, 16 envs, horizon 8."""

import dataclasses

from _common import GYM, NetConfig, composite


def config():
    cfg = composite((GYM + "chest_open+walk_in_place.json",), (GYM + "squat.json",))
    return dataclasses.replace(
        cfg,
        net=NetConfig(policy_hidden=(64, 64), critic_hidden=(64, 64), disc_hidden=(32, 32), disc_heads=4),
        ppo=dataclasses.replace(
            cfg.ppo, num_envs=16, horizon=8, minibatch_size=64, epochs=2, actor_lr=3e-4, critic_lr=1e-3
        ),
        disc=dataclasses.replace(cfg.disc, lr=1e-4, minibatch_size=64),
        iterations=6,
        chunk=2,
        checkpoint_every=1,
        eval_every=0,
    )
