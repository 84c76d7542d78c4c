"""Imitation pretraining of Won et al. 2021's mixture of experts (§4.2) on the boxing clips: the
scene, clips and discriminator of `imitate/boxing`, with the paper's boxing policy: 8 motor experts
(64-64, reading only the body state) gated by an encoder (128-128) whose weights are smoothed with
α = 0.9 (`nets/moe.py`). The actor's learning rate is the authors' imitation rate, 2e-5. Its
experts are the decoder that `boxing/selfplay_moe` keeps (`decoder_from`)."""

import dataclasses

from jaxmotion.config.experiments import load_experiment


def config():
    cfg = load_experiment("imitate/boxing")
    net = dataclasses.replace(cfg.net, policy="moe", experts=8, gate_alpha=0.9, state_dependent_std=False)
    return dataclasses.replace(cfg, net=net, ppo=dataclasses.replace(cfg.ppo, actor_lr=2e-5))
