"""Full-body imitation of the boxing clips (two punches, walk, jog) with one discriminator
ensemble, at the bouts' settings (240-Hz physics; the current frame only as body state, as the
bout's policy sees it), CPU-sized networks (256-256). It is the frozen meta policy that
`boxing/selfplay_meta` builds on, so that the boxers start able to stand, step and punch (Won et
al. pretrain on imitation for the same reason; their mixture-of-experts is a later issue)."""

from _common import BOXING_CLIPS, EnvConfig, GroupConfig, NetConfig, PPOConfig, TrainConfig
from jaxmotion.physics.sim import PhysicsConfig


def config():
    env = EnvConfig(
        physics=PhysicsConfig(sim_hz=240.0),
        init_motions=BOXING_CLIPS,
        policy_frames=1,
        groups=(GroupConfig(name="full", motions=BOXING_CLIPS),),
    )
    return TrainConfig(
        env=env,
        net=NetConfig(policy_hidden=(256, 256), critic_hidden=(256, 256)),
        ppo=PPOConfig(),
        iterations=3000,
        chunk=10,
        eval_every=25,
    )
