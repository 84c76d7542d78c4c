"""Shared pieces of the experiment files (files starting with '_' are not experiments)."""

from jaxmotion.envs.humanoid import EnvConfig, GroupConfig
from jaxmotion.trainer import DiscConfig, NetConfig, PPOConfig, TrainConfig  # noqa: F401 (re-exported)

WALK = (
    "compositemotion/locomotion/lafan1_walk1_subject1_100_1170.json",
    "compositemotion/locomotion/lafan1_walk1_subject1_2460_3680.json",
    "compositemotion/locomotion/lafan1_walk1_subject5_5740_6830.json",
    "compositemotion/locomotion/lafan1_walk1_subject5_80_1715.json",
)
GYM = "compositemotion/gym/"


def composite(upper: tuple[str, ...], lower: tuple[str, ...], weights=(0.5, 0.5),
              upper_speed=(0.8, 1.2), episode_steps: int = 300) -> TrainConfig:
    """Upper body from ``upper`` clips (pelvis anchor), lower body from ``lower`` (heading frame).

    Defaults follow the paper and the authors' code: 512 envs x horizon 8, minibatch 256, 5
    epochs, lr 5e-6 / 1e-4 / 1e-5, 32-head discriminators with gradient penalty 10, random replay
    speed 0.8-1.2 on the upper-body reference only, reference-state init from the lower clips.
    """
    env = EnvConfig(
        init_motions=lower,
        groups=(GroupConfig(name="upper", motions=upper, speed_range=upper_speed),
                GroupConfig(name="lower", motions=lower)),
        episode_steps=episode_steps)
    return TrainConfig(env=env, ppo=PPOConfig(objective_weights=weights), iterations=5000, chunk=10,
                       eval_every=25)
