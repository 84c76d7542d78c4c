"""Fencing self-play on the 12 m x 2 m piste with the sword-and-shield characters (the shield
stays: it blocks and is never a target), one shared policy, the paper's 20-s limit, the first
touch wins unless countered within 1 s; sized for a CPU (32 bouts in parallel).

Measured on the 2-core CPU (2026-12-05; `make train EXP=fencing/selfplay ARGS="iterations=1500"`,
0.77M player-steps, 5.8 min; `python -m jaxmotion.eval <run> --bouts 32`): from a random MLP the
players never close in (start 4 m apart, r_close 0.000 throughout), bouts last 1.4 s, no touches,
every bout ends by a fall. Like `boxing/selfplay_meta`, it needs an imitation policy to start
from."""

from _common import bout


def config():
    return bout("fencing", round_s=20.0)
