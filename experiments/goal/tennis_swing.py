"""Tennis swing (paper §6.1, §6.4; task `tennis`, `tasks/tennis.py`): hit a fed ball with a
racket towards a landing target 8-12 m ahead, while the upper body moves like a sword slash and
the lower body like sword-fighting footwork.

No tennis clips exist in the shared data (the paper's are commercial), so this is a substitute:
the sword-and-shield character (its 3-DoF right wrist) with a racket in the sword's place and
no shield (`PhysicsConfig.racket`); the upper body (torso, head, arms, the racket; pelvis
anchor; replay speed 0.8-1.2) imitates ASE's slashes and the in-place swing (`Atk_SlashRight`,
`Atk_SlashLeft`, `Standoff_Swing`), the lower body (heading frame) the idle stances and the
circling footwork (`Idle_Ready`, `Idle_Battle`, `Standoff_Circle`), which also start the episodes.
The paper's reward formula is in an appendix we do not have; ours (`tasks/tennis.py`): one ball
every 2 s, tossed beside the character on its racket side; a hit pays 0.5 min(speed / 10 m/s, 1)
+ 0.5 exp(-d^2 / 8) for landing d metres from the target, once, when the ball leaves the racket;
a reach term (racket head to ball, until the hit) is our shaping. ω 0.25 upper / 0.25 lower /
0.35 hit / 0.15 reach. 240-Hz physics: at 120 Hz the ball passes through the racket
(`physics/props.py`). 10-s episodes: five balls each. Results: docs/results.md, "Tennis swing".
"""

import dataclasses

from _common import ASE, GroupConfig, TaskConfig, goal

from jaxmotion.physics.props import PropConfig
from jaxmotion.physics.sim import PhysicsConfig

SWING = tuple(ASE + n + "_Motion.npy" for n in ("Atk_SlashRight", "Atk_SlashLeft", "Standoff_Swing"))
FOOTWORK = tuple(ASE + n + "_Motion.npy" for n in ("Idle_Ready", "Idle_Battle", "Standoff_Circle"))


def config():
    cfg = goal(
        TaskConfig(name="tennis"),
        (GroupConfig(name="upper", motions=SWING, speed_range=(0.8, 1.2)), GroupConfig(name="lower", motions=FOOTWORK)),
        FOOTWORK,
    )
    physics = PhysicsConfig(sword_shield=True, racket=True, props=(PropConfig(),), sim_hz=240.0)
    return dataclasses.replace(cfg, env=dataclasses.replace(cfg.env, physics=physics, episode_steps=300))
