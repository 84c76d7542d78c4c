"""Fencing self-play on the 12 m x 2 m piste with the sword-and-shield characters (the shield
stays: it blocks and is never a target), one shared policy, the paper's 20-s limit, the first
touch wins unless countered within 1 s; sized for a CPU (32 bouts in parallel).
Results: docs/results.md, "Fencing".
"""

from _common import bout


def config():
    return bout("fencing", round_s=20.0)
