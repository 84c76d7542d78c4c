"""chest_open+squat sized for a CPU: the experiment a CPU user runs for paper Table 1, row 3.

256-256 policy and critic instead of 1024-512, and the gradient penalty of the summed heads (the
authors' code; now also the library default). Everything else, learning rates included, as the
paper; on a CPU the physics runs on MuJoCo C inside the compiled loop (``env.physics.backend``
``auto``). 5000 iterations = 20.5M samples, the paper's budget, are the default length. The lower
reference is one squat (ours: ``_common.SQUAT``, the shared clip without the bounce at its
bottom). Results and their history: docs/results.md, "Table 1, chest open and squat".
"""

import dataclasses

from _common import GYM, SQUAT, composite


def config():
    cfg = composite((GYM + "chest_open+walk_in_place.json",), (SQUAT,))
    return dataclasses.replace(
        cfg,
        net=dataclasses.replace(cfg.net, policy_hidden=(256, 256), critic_hidden=(256, 256)),
        disc=dataclasses.replace(cfg.disc, gp_mode="sum_heads"),
    )
