"""The progressive pipeline in miniature, sized for a 2-core CPU: `track/small`'s three clips
(walk, run, punch), two primitives (the second on the clips the first fails), each frozen after
2 mining passes (every 100 iterations) without a rise or 600 iterations, then a composer over
both for 300 iterations. `init_from=<a track/small run>` starts primitive 1 from a trained
tracker. Results: docs/tracker.md, "Progressive primitives on a CPU".
"""

import dataclasses

from _common import track

from jaxmotion.training.hparams import ProgressiveConfig


def config():
    cfg = track(
        ("deepmimic/humanoid3d_walk.txt", "deepmimic/humanoid3d_run.txt", "deepmimic/humanoid3d_punch.txt"),
        iterations=3000,
    )
    return dataclasses.replace(
        cfg,
        hard_negatives_every=10,
        progressive=ProgressiveConfig(primitives=2, stage_iterations=600, patience=2, composer_iterations=300),
    )
