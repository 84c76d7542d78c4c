"""Boxing self-play on top of a frozen imitation policy (`imitate/boxing`): the shared policy is
the incremental one of paper Xu et al. §5 (`training/meta.py`): each player's action is
mu + w * a_meta, a_meta sampled from the imitation policy on the player's own body state, w one
weight per DoF starting at 0.95 with its own learning rate 1e-3 (ours). So the boxers start as the
imitation policy (standing, stepping, punching) instead of a random Gaussian MLP whose bouts all
ended by a fall within a second (`boxing/selfplay`). Same ring, rules, ω and PPO settings as
`boxing/selfplay` (60-s rounds, damage per hit onset).

Train the imitation policy first (`make train EXP=imitate/boxing`); `meta` takes its newest run,
or name one: `make train EXP=boxing/selfplay_meta ARGS="meta=runs/imitate/boxing/<stamp>"`.
Results: docs/sports.md, "Boxing on an imitation policy".
"""

import dataclasses

from _common import bout


def config():
    cfg = bout("boxing", round_s=60.0)
    return dataclasses.replace(cfg, meta="runs/imitate/boxing", ppo=dataclasses.replace(cfg.ppo, meta_weight_lr=1e-3))
