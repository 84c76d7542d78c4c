"""Aiming + target location while walking, from scratch (the authors' `config/aim+locomotion_walk.py`):
4 objectives, ω 0.2 aim upper body / 0.3 walk lower body / 0.25 location / 0.25 aim. The upper
body (torso, head, arms; pelvis anchor; a 2-frame window; replay speed 0.8-1.2) imitates the two
LAFAN1 aiming clips, the lower body the walk clips; the right forearm is the weapon.

Measured on the 2-core CPU (2026-12-04, seed 0; `make train EXP=goal/aim+walk
ARGS="eval_every=10"` stopped at 7.0M samples, then `python -m jaxmotion.eval <run> --episodes 16`):
upper / lower DTW 0.108 / 0.115 m (coverage 99% / 100%), aim error 52 deg, aim reward 0.34,
2 falls in 16 episodes (14.7 s of 16.7 on average), 7 of 52 goals reached (13%), mean distance
3.3 m. Every evaluation fell until 2.5M samples; full-length episodes from 3.24M. The video shows
a walk with both arms held forward as in the aiming clips, the right forearm along the aim arrow.
The comparison with `incremental/aim+walk` is in the README ("Incremental vs scratch")."""

import dataclasses

from _common import AIM, WALK, LOCATION_WALK, GroupConfig, TaskConfig, goal


def config():
    return goal(TaskConfig(name="aim+location", location=dataclasses.replace(LOCATION_WALK, weight=0.25)),
                (GroupConfig(name="upper", motions=AIM, frames=2, speed_range=(0.8, 1.2), weight=0.2),
                 GroupConfig(name="lower", motions=WALK, weight=0.3)), WALK)
