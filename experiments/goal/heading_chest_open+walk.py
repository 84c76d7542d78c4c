"""Target heading with chest_open upper body and walk lower body (paper Fig. 5a). The heading task is
our definition (the paper's formula is in an appendix we do not have; `tasks/location.py`):
the goal is a world direction and a speed, the reward the authors' velocity-matching term with
the target at infinity. ω 0.25 upper / 0.25 lower / 0.5 heading, as the authors run these pairs
(there as location tasks). Upper body from `gym/chest_open+walk_in_place` (pelvis anchor, replay speed 0.8-1.2),
lower body from the four walk clips.

Measured on the 2-core CPU (2026-12-05; `make train EXP=goal/heading_chest_open+walk
ARGS="iterations=2000"`, 8.2M samples, 1 h 50 min beside three other jobs; `python -m jaxmotion.eval
<run> --episodes 16`): no falls (16 full 16.7-s episodes), heading error 8.1 deg, speed error
0.19 m/s, heading reward 0.75, upper / lower DTW 0.057 / 0.114 m. Untrained (`--untrained`): all 16
fall within 0.75 s, 75.4 deg, 0.32 m/s, 0.147 / 0.224 m."""

from _common import GYM, WALK, GroupConfig, TaskConfig, goal


def config():
    return goal(TaskConfig(name="heading"),
                (GroupConfig(name="upper", motions=(GYM + "chest_open+walk_in_place.json",), speed_range=(0.8, 1.2)),
                 GroupConfig(name="lower", motions=WALK)), WALK)
