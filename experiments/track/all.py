"""Track every shared clip on the 15-body humanoid (notes phc.md §7): the 95 distinct clips, the
sword-and-shield ones without their props, minus the 15 of the development split
`_common.TRACK_DEV`: 80 clips, 598 s; the rotation goal (15 x 24 goal features). Evaluate on the
held-out clips with `python -m jaxmotion.eval <run> --clips <dev clip paths>`.

Measured on one H200 (2026-12-04; `ARGS="ppo.num_envs=4096 ppo.minibatch_size=2048
disc.minibatch_size=2048 ppo.actor_lr=2e-5"`, 12.8M samples in 5.6 min at 61k samples/s), evaluated
on the CPU with MuJoCo C: 2/80 training clips tracked to the end (untrained 0/80), 0/15 held-out
clips; a clip is followed for 1.07 s on average before the mean body error passes 0.5 m (untrained
0.71 s). README "Motion tracking" has the table."""

from _common import TRACK_TRAIN, track


def config():
    return track(TRACK_TRAIN)
