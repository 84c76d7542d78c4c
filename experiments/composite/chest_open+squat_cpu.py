"""chest_open+squat sized for a CPU: 256-256 policy and critic instead of 1024-512, and the
gradient penalty of the summed heads (the authors' code) instead of one per head (paper Eq. 2),
which needs 32 backward passes. Everything else, learning rates included, as the paper.

On a 2-core CPU at batch 256 this brings a full training iteration from about 5.6x the
physics-only cost (paper sizes) to about 1.3x (rollout, discriminator and PPO steps timed
separately; ``make bench BENCH_ARGS="--exp composite/chest_open+squat_cpu"`` measures it).
"""
import dataclasses

from _common import GYM, composite


def config():
    cfg = composite((GYM + "chest_open+walk_in_place.json",), (GYM + "squat.json",))
    return dataclasses.replace(
        cfg,
        net=dataclasses.replace(cfg.net, policy_hidden=(256, 256), critic_hidden=(256, 256)),
        disc=dataclasses.replace(cfg.disc, gp_mode="sum_heads"))
