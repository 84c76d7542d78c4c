"""Full-body imitation of the four LAFAN1 walk clips with one discriminator ensemble."""

from _common import WALK, EnvConfig, GroupConfig, PPOConfig, TrainConfig


def config():
    env = EnvConfig(init_motions=WALK, groups=(GroupConfig(name="full", motions=WALK),))
    return TrainConfig(env=env, ppo=PPOConfig(), iterations=5000, chunk=10, eval_every=25)
