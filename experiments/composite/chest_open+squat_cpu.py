"""chest_open+squat sized for a CPU: 256-256 policy and critic instead of 1024-512, and the
gradient penalty of the summed heads (the authors' code) instead of one per head (paper Eq. 2),
which needs the input gradient of each of the 32 heads at every sample. Everything else,
learning rates included, as the paper.

On 2 CPU cores, ``make bench BENCH_ARGS="--exp <name>"`` measured a full training iteration at
1.28x the physics-only cost at batch 256 (1569 vs 2000 control steps/s); the paper-sized
``composite/chest_open+squat`` measured 2.12x (824 vs 1743), and 1.80x with only the summed-head
penalty (README, Performance).
"""
import dataclasses

from _common import GYM, composite


def config():
    cfg = composite((GYM + "chest_open+walk_in_place.json",), (GYM + "squat.json",))
    return dataclasses.replace(
        cfg,
        net=dataclasses.replace(cfg.net, policy_hidden=(256, 256), critic_hidden=(256, 256)),
        disc=dataclasses.replace(cfg.disc, gp_mode="sum_heads"))
