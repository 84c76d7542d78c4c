"""Boxing self-play in the roped ring (5 m inside the ropes), one shared policy for both players,
the paper's 60-s rounds (1800 steps at 30 Hz, in training and evaluation), sized for a CPU (32
bouts in parallel). Damage is paid per hit, at its onset, with the authors' 0.5-s interval
(``env.task.boxing.touch_interval``). Starts from the punch and walk clips; evaluate with
`python -m jaxmotion.eval <run> [--against <other-run>] --bouts 32`."""

from _common import bout


def config():
    return bout("boxing", round_s=60.0)
