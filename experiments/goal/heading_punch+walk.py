"""Target heading with punch upper body and walk lower body (paper Fig. 5a). The heading task is
our definition (the paper's formula is in an appendix we do not have; `tasks/location.py`):
the goal is a world direction and a speed, the reward the authors' velocity-matching term with
the target at infinity. ω 0.25 upper / 0.25 lower / 0.5 heading, as the authors run these pairs
(there as location tasks). Upper body from `gym/punch` (pelvis anchor, replay speed 0.8-1.2),
lower body from the four walk clips.

Measured on the 2-core CPU (5000 iterations, 20.5M samples, 2 h): heading error 11.0° and speed
error 0.18 m/s over 16 evaluation episodes (untrained: 75°, 0.32 m/s), upper / lower DTW 0.078 /
0.109 m, 6 of 16 episodes fall (untrained: all, within 0.75 s); README, Tasks."""

from _common import GYM, WALK, GroupConfig, TaskConfig, goal


def config():
    return goal(TaskConfig(name="heading"),
                (GroupConfig(name="upper", motions=(GYM + "punch.json",), speed_range=(0.8, 1.2)),
                 GroupConfig(name="lower", motions=WALK)), WALK)
