"""Fail-state recovery in miniature, sized for a 2-core CPU: the four LAFAN1 walks (35-55 s
each: a far start needs a reference that lasts while the character catches up, as the authors'
locomotion clips do), DeepMimic's walk and face-down get-up, tracked with the recovery starts,
point goal and recovery episodes of ``tasks/recovery.py``: the authors' settings, except that half
the reference-state starts are far ones (theirs: all) within 4 m (theirs: 5), so that a CPU-sized
budget keeps tracking from the reference too. Start it from a trained tracker
(``init_from=<a track/small run>``); evaluate with ``python -m jaxmotion.eval RUN --recovery``.
Results: docs/tracker.md, "Recovery on a CPU".
"""

import dataclasses

from _common import WALK, track

from jaxmotion.tasks.recovery import RecoveryConfig


def config():
    cfg = track(
        (*WALK, "deepmimic/humanoid3d_walk.txt", "deepmimic/humanoid3d_getup_facedown.txt"),
        iterations=3000,
    )
    recovery = RecoveryConfig(enabled=True, far_prob=0.5, far_start=(0.0, 4.0))
    track_cfg = dataclasses.replace(cfg.env.task.track, recovery=recovery)
    task = dataclasses.replace(cfg.env.task, track=track_cfg)
    return dataclasses.replace(cfg, env=dataclasses.replace(cfg.env, task=task))
