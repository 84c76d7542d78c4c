"""Target heading with punch upper body and walk lower body (paper Fig. 5a). The heading task is
our definition (the paper's formula is in an appendix we do not have; `tasks/location.py`):
the goal is a world direction and a speed, the reward the authors' velocity-matching term with
the target at infinity. ω 0.25 upper / 0.25 lower / 0.5 heading, as the authors run these pairs
(there as location tasks). Upper body from `gym/punch` (pelvis anchor, replay speed 0.8-1.2),
lower body from the four walk clips. Results: docs/results.md, "Heading while punching".
"""

from _common import GYM, WALK, GroupConfig, TaskConfig, goal


def config():
    return goal(
        TaskConfig(name="heading"),
        (
            GroupConfig(name="upper", motions=(GYM + "punch.json",), speed_range=(0.8, 1.2)),
            GroupConfig(name="lower", motions=WALK),
        ),
        WALK,
    )
