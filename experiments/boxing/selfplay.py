"""Boxing self-play in the roped ring (5 m inside the ropes), one shared policy for both players,
10-s rounds (the paper's are 60 s: ``env.episode_steps=1800``), sized for a CPU (32 bouts in
parallel). Starts from the punch and walk clips; evaluate with
`python -m jaxmotion.eval <run> [--against <other-run>] --bouts 32`."""

from _common import bout


def config():
    return bout("boxing", round_s=10.0)
