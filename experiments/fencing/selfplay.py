"""Fencing self-play on the 12 m x 2 m piste with the sword-and-shield characters (the shield
stays: it blocks and is never a target), one shared policy, the paper's 20-s limit, the first
touch wins unless countered within 1 s; closeness exp(-3 d) (the authors' form: the paper's
exp(-3 d^2) is ~1e-14 at the 4-m start, ``env.task.fencing.close_squared=true``); sized for a
CPU (32 bouts in parallel).
Results: docs/sports.md, "Fencing".
"""

from _common import bout


def config():
    return bout("fencing", round_s=20.0)
