"""Progressive multiplicative control (PHC §3.2) on `track/all`'s 80 training clips: primitive 1
on all of them, primitives 2 and 3 each from its predecessor on the clips it failed, each frozen
when its success stops rising (3 mining passes, 6M samples, without a rise), then a composer
over them (`training/progressive.py`). Continue a stopped pipeline with `resume=<its folder>`;
evaluate its composer with `python -m jaxmotion.eval <its folder>`.
"""

import dataclasses

from _common import TRACK_TRAIN, track

from jaxmotion.training.hparams import ProgressiveConfig


def config():
    cfg = track(TRACK_TRAIN)
    return dataclasses.replace(
        cfg, progressive=ProgressiveConfig(primitives=3, stage_iterations=20000, patience=3, composer_iterations=10000)
    )
