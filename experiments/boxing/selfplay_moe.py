"""Boxing self-play with Won et al. 2021's policy and training (§4.3-4.4): the mixture of experts
pretrained on imitation (`imitate/boxing_moe`) keeps its motor decoder (8 experts, α 0.9) and gets
a new encoder for the bout's observation (`decoder_from`); the encoder learns alone first, then
end-to-end and encoder-only turns alternate (`decoder_start`, `decoder_every`). The paper counts
300-500 and 50 iterations of 150k samples; this CPU-sized run has 512 samples an iteration, so the
turns here are 1000 and 500 iterations (0.5M and 0.26M samples). Same ring, rules, ω and PPO
settings as `boxing/selfplay` (60-s rounds, damage per hit onset).

Pretrain first (`make train EXP=imitate/boxing_moe`); `decoder_from` takes its newest run, or name
one: `make train EXP=boxing/selfplay_moe ARGS="decoder_from=runs/imitate/boxing_moe/<stamp>"`."""

import dataclasses

from _common import bout


def config():
    cfg = bout("boxing", round_s=60.0)
    net = dataclasses.replace(cfg.net, policy="moe", experts=8, gate_alpha=0.9)
    return dataclasses.replace(
        cfg, net=net, decoder_from="runs/imitate/boxing_moe", decoder_start=1000, decoder_every=500
    )
