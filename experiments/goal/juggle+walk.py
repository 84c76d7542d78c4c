"""Juggling three balls while walking to a target location (the authors'
`ICCGANHumanoidJugglingTarget`, paper Fig. 5d; task `juggle+location`, `tasks/juggle.py`).

Two body groups: the arms (both upper arms, forearms and hands; torso anchor; replay speed
0.8-1.2) imitate the juggling clip (FreeMoCap demo, 24.6 s); the torso, head, pelvis and legs
(heading frame) the LAFAN1 walk clips. ω 0.06 arms / 0.24 body / 0.6 juggling / 0.1 location,
as the authors. Location settings for juggling (notes §1): radius 0.75 m, speed 1-1.2 m/s,
timers 90-149 steps, goals within ±60° at v0 = 1 m/s, no overshoot termination. The balls are
free bodies of the MuJoCo scene (r 0.05 m, 57 g, no bounce; they pass through the body and each
other): see `tasks/juggle.py`. Results: docs/results.md, "Juggling while walking".
"""

from _common import WALK, GroupConfig, LocationConfig, TaskConfig, goal

ARMS = ("right_upper_arm", "right_lower_arm", "right_hand", "left_upper_arm", "left_lower_arm", "left_hand")
BODY = ("pelvis", "torso", "head", "right_thigh", "right_shin", "right_foot", "left_thigh", "left_shin", "left_foot")
LOCATION_JUGGLE = LocationConfig(
    radius=0.75,
    speed_range=(1.0, 1.2),
    timer_range=(90, 150),
    v0_mean=1.0,
    v0_std=0.0,
    v0_range=(1.0, 1.0),
    sharp_turns=False,
    max_overshoot=0.0,
    weight=0.1,
)


def config():
    import dataclasses

    from jaxmotion.physics.props import PropConfig
    from jaxmotion.tasks import JuggleConfig

    cfg = goal(
        TaskConfig(name="juggle+location", location=LOCATION_JUGGLE, juggle=JuggleConfig(weight=0.6)),
        (
            GroupConfig(
                name="arms",
                motions=("compositemotion/gym/juggling.json",),
                links=ARMS,
                anchor="torso",
                speed_range=(0.8, 1.2),
                weight=0.06,
            ),
            GroupConfig(name="body", motions=WALK, links=BODY, anchor="heading", weight=0.24),
        ),
        WALK,
    )
    balls = tuple(PropConfig(name=f"ball{i}", radius=0.05, mass=0.057, restitution=0.0) for i in range(3))
    physics = dataclasses.replace(cfg.env.physics, props=balls)
    return dataclasses.replace(cfg, env=dataclasses.replace(cfg.env, physics=physics))
