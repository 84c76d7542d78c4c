"""chest_open+squat sized for a CPU: 256-256 policy and critic instead of 1024-512, and the
gradient penalty of the summed heads (the authors' code) instead of one per head (paper Eq. 2),
which needs 32 backward passes. Everything else, learning rates included, as the paper.

On a 2-core CPU at batch 256, ``make bench BENCH_ARGS="--batches 256 --exp <name>"`` measured a
full training iteration at 2.9x the physics-only cost with the paper's sizes (469 vs 1379 control
steps/s) and 1.5x with these (936 vs 1410).
"""
import dataclasses

from _common import GYM, composite


def config():
    cfg = composite((GYM + "chest_open+walk_in_place.json",), (GYM + "squat.json",))
    return dataclasses.replace(
        cfg,
        net=dataclasses.replace(cfg.net, policy_hidden=(256, 256), critic_hidden=(256, 256)),
        disc=dataclasses.replace(cfg.disc, gp_mode="sum_heads"))
