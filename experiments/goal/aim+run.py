"""Aiming + target location while running, from scratch (the authors' `config/aim+locomotion_run.py`):
4 objectives, ω 0.2 aim upper body / 0.3 run lower body / 0.25 location / 0.25 aim. The upper
body (torso, head, arms; pelvis anchor; a 2-frame window; replay speed 0.8-1.2) imitates the two
LAFAN1 aiming clips, the lower body the run clips; the right forearm is the weapon."""

import dataclasses

from _common import AIM, RUN, LOCATION_RUN, GroupConfig, TaskConfig, goal


def config():
    return goal(
        TaskConfig(name="aim+location", location=dataclasses.replace(LOCATION_RUN, weight=0.25)),
        (
            GroupConfig(name="upper", motions=AIM, frames=2, speed_range=(0.8, 1.2), weight=0.2),
            GroupConfig(name="lower", motions=RUN, weight=0.3),
        ),
        RUN,
    )
