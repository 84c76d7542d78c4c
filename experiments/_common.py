"""Shared pieces of the experiment files (files starting with '_' are not experiments)."""

from jaxmotion.envs.humanoid import EnvConfig, GroupConfig
from jaxmotion.tasks import AimConfig, HeadingConfig, LocationConfig, TaskConfig  # noqa: F401 (re-exported)
from jaxmotion.training.learner import DiscConfig, NetConfig, PPOConfig, TrainConfig  # noqa: F401 (re-exported)

WALK = (
    "compositemotion/locomotion/lafan1_walk1_subject1_100_1170.json",
    "compositemotion/locomotion/lafan1_walk1_subject1_2460_3680.json",
    "compositemotion/locomotion/lafan1_walk1_subject5_5740_6830.json",
    "compositemotion/locomotion/lafan1_walk1_subject5_80_1715.json",
)
GYM = "compositemotion/gym/"
# One squat: the shared clip (2.83 s) bounces at the bottom between two squats' lowest points
# (frames 32-58); a policy sees the same state rising from either and may loop the bounce for
# ever. Frames 0-27 and 56-84 join seamlessly (6 mm, 0.12 m/s apart) into one 1.87-s squat
# (the paper's is 1.67 s).
SQUAT = GYM + "squat.json[0:28,56:]"


def composite(
    upper: tuple[str, ...], lower: tuple[str, ...], weights=(0.5, 0.5), upper_speed=(0.8, 1.2), episode_steps: int = 300
) -> TrainConfig:
    """Upper body from ``upper`` clips (pelvis anchor), lower body from ``lower`` (heading frame).

    Defaults follow the paper and the authors' code: 512 envs x horizon 8, minibatch 256, 5
    epochs, lr 5e-6 / 1e-4 / 1e-5, 32-head discriminators with gradient penalty 10, random replay
    speed 0.8-1.2 on the upper-body reference only, reference-state init from the lower clips.
    """
    env = EnvConfig(
        init_motions=lower,
        groups=(
            GroupConfig(name="upper", motions=upper, speed_range=upper_speed),
            GroupConfig(name="lower", motions=lower),
        ),
        episode_steps=episode_steps,
    )
    return TrainConfig(env=env, ppo=PPOConfig(objective_weights=weights), iterations=5000, chunk=10, eval_every=25)


LOCO = "compositemotion/locomotion/"
RUN = (LOCO + "lafan1_run1_subject5_160_2105.json", LOCO + "lafan1_run2_subject1_145_2445.json")
CROUCH = (LOCO + "crouch_lafan1_walk3_subject5_2490_2735.json", LOCO + "crouch_lafan1_walk3_subject5_320_1410.json")
AIM = (
    "compositemotion/aiming/lafan1_aiming2_subject3_140_970.json",
    "compositemotion/aiming/lafan1_aiming2_subject3_2940_3575.json",
)

# The authors' location settings per locomotion style (notes §1): walk and crouch share them.
LOCATION_WALK = LocationConfig()
LOCATION_RUN = LocationConfig(
    speed_range=(2.0, 4.0), timer_range=(60, 90), v0_mean=1.5, v0_std=0.5, v0_range=(1.0, 3.0)
)


def goal(
    task: TaskConfig, groups: tuple[GroupConfig, ...], init: tuple[str, ...], iterations: int = 5000
) -> TrainConfig:
    """A goal task over body-group imitation, sized for a CPU (256-256 policy and critic; the
    paper's 1024-512 is ``net.policy_hidden=1024,512 net.critic_hidden=1024,512``).

    Episodes of 500 control steps (16.7 s) and reference-state initialisation from the
    locomotion clips, as the authors' code; ω by the authors' rule (groups' ``weight`` and the
    task's weights, ``tasks.combine_weights``). The paper trains these for 1-4 x 10^8 samples;
    ``iterations`` 5000 is 20.5M.
    """
    env = EnvConfig(init_motions=init, groups=groups, episode_steps=500, task=task)
    return TrainConfig(
        env=env,
        net=NetConfig(policy_hidden=(256, 256), critic_hidden=(256, 256)),
        ppo=PPOConfig(),
        iterations=iterations,
        chunk=10,
        eval_every=25,
    )


def incremental(scratch: str, meta: str) -> TrainConfig:
    """Experiment ``scratch`` learned incrementally on the frozen policy of ``meta`` (a run
    folder, or an experiment's folder of runs: its newest run; ``jaxmotion/meta.py``)."""
    import dataclasses

    from jaxmotion.config.experiments import load_experiment

    return dataclasses.replace(load_experiment(scratch), meta=meta)


# ---- motion tracking (Perpetual Humanoid Control; notes phc.md §7) ---------------------------------
# Development split: held out of training, each with a close sibling in training (notes phc.md §7).
# The sword-and-shield clips (17 bodies) are tracked with the sword, shield and wrist dropped.
ASE = "ase_sword_shield/RL_Avatar_"
TRACK_DEV = tuple(
    ASE + n + "_Motion.npy"
    for n in (
        "Atk_SlashLeft",
        "Sword_ParryBackward03",
        "Shield_BlockLeft",
        "RunLeft",
        "Dodgle_Right",
        "TurnRight90",
        "Fall_SpinRight",
    )
) + (
    "compositemotion/locomotion/lafan1_walk1_subject5_5740_6830.json",
    "compositemotion/locomotion/crouch_lafan1_walk3_subject5_2490_2735.json",
    "compositemotion/aiming/lafan1_aiming2_subject3_2940_3575.json",
    "compositemotion/iccgan/limp_walk.json",
    "deepmimic/humanoid3d_jog.txt",
    "deepmimic/humanoid3d_spinkick.txt",
    "deepmimic/humanoid3d_getup_faceup.txt",
    "isaacgymenvs/amp_humanoid_walk.npy",
)
_ASE_CLIPS = (
    "Atk_2xCombo01",
    "Atk_3xCombo01",
    "Atk_Jump",
    "Atk_Kick",
    "Atk_ShieldCharge",
    "Atk_ShieldSwipe01",
    "Atk_ShieldSwipe02",
    "Atk_SlashDown",
    "Atk_SlashLeft",
    "Atk_SlashRight",
    "Atk_SlashUp",
    "Atk_Spin",
    "Atk_Stab",
    "Counter_Atk01",
    "Dodge_Backward",
    "Dodgle_Left",
    "Dodgle_Right",
    "Fall_Backward",
    "Fall_Left",
    "Fall_Right",
    "Fall_SpinLeft",
    "Fall_SpinRight",
    "Idle_Alert",
    "Idle_Battle",
    "Idle_Ready",
    "RunBackward",
    "RunForward",
    "RunLeft",
    "RunRight",
    "Shield_BlockBackward",
    "Shield_BlockCrouch",
    "Shield_BlockDown",
    "Shield_BlockLeft",
    "Shield_BlockRight",
    "Shield_BlockUp",
    "Standoff_Circle",
    "Standoff_Swing",
    "Sword_ParryBackward01",
    "Sword_ParryBackward02",
    "Sword_ParryBackward03",
    "Sword_ParryBackward04",
    "Sword_ParryCrouch",
    "Sword_ParryDown",
    "Sword_ParryLeft",
    "Sword_ParryRight",
    "Sword_ParryUp",
    "TurnLeft90",
    "TurnRight180",
    "TurnRight90",
    "WalkBackward01",
    "WalkForward01",
    "WalkRight01",
)
# Every clip of the shared data not in the dev split (sword-and-shield ones without their props); the
# duplicates of notes §7 (iccgan/punch = gym/punch, amp_humanoid_backflip = deepmimic backflip) counted once.
TRACK_TRAIN = tuple(
    p
    for p in (
        [
            LOCO + n
            for n in (
                "crouch_lafan1_walk3_subject5_320_1410.json",
                "lafan1_run1_subject5_160_2105.json",
                "lafan1_run2_subject1_145_2445.json",
                "lafan1_walk1_subject1_100_1170.json",
                "lafan1_walk1_subject1_2460_3680.json",
                "lafan1_walk1_subject5_80_1715.json",
            )
        ]
        + ["compositemotion/aiming/lafan1_aiming2_subject3_140_970.json"]
        + [
            GYM + n + ".json"
            for n in (
                "chest_open+walk_in_place",
                "front_jumping_jack",
                "juggling",
                "leg_lunge",
                "punch",
                "squat",
                "waist_twist",
            )
        ]
        + [
            "compositemotion/iccgan/" + n + ".json"
            for n in ("joyful_walk", "kick", "long_jump", "roll", "spinning_jump", "stoop_walk")
        ]
        + [
            "deepmimic/humanoid3d_" + n + ".txt"
            for n in (
                "backflip",
                "cartwheel",
                "crawl",
                "dance_a",
                "dance_spin",
                "getup_facedown",
                "jump",
                "kick",
                "punch",
                "roll",
                "run",
                "sideflip",
                "walk",
            )
        ]
        + ["isaacgymenvs/amp_humanoid_" + n + ".npy" for n in ("cartwheel", "run")]
        + [ASE + n + "_Motion.npy" for n in _ASE_CLIPS]
    )
    if p not in TRACK_DEV
)


def track(
    clips: tuple[str, ...],
    goal: str = "rotation",
    iterations: int = 5000,
    residual: bool = True,
    init_sampling: str = "duration",
) -> TrainConfig:
    """A tracker of ``clips`` (PHC's imitation reward + a 10-frame full-body motion prior, ω 0.5 /
    0.5; reference-state init at random times; no contact termination, the distance rule instead;
    a fixed σ = e^-2.9 and the actor's learning rate 2e-5, as the authors'; hard-negative mining
    every 2M samples), sized for a CPU (256-256 networks; the paper's are 1024-512-256). The
    servo is the default one, its damping inside the clipped actuator: joint damping caps a joint
    below the clips' speeds (docs/physics.md). Departure from the authors' code: the PD target
    is the reference's next-frame joint angles + the action (``track.residual``). The
    measurements behind these choices: docs/tracker.md, "Three clips on a CPU"."""
    from jaxmotion.tasks import TrackConfig

    env = EnvConfig(
        init_motions=clips,
        groups=(GroupConfig(name="full", motions=clips, frames=10),),
        episode_steps=300,
        policy_frames=1,
        early_termination=False,
        drop_props=True,
        init_sampling=init_sampling,
        task=TaskConfig(name="track", track=TrackConfig(goal=goal, residual=residual)),
    )
    return TrainConfig(
        env=env,
        net=NetConfig(policy_hidden=(256, 256), critic_hidden=(256, 256), state_dependent_std=False, init_log_std=-2.9),
        ppo=PPOConfig(actor_lr=2e-5),
        iterations=iterations,
        chunk=10,
        eval_every=0,
        hard_negatives_every=50,
    )


# ---- two-player sports (Won et al. 2021; notes won2021.md §7) ------------------------------------
BOXING_CLIPS = (
    "deepmimic/humanoid3d_punch.txt",
    "compositemotion/iccgan/punch.json",
    "deepmimic/humanoid3d_walk.txt",
    "deepmimic/humanoid3d_jog.txt",
)
FENCING_CLIPS = tuple(
    ASE + n + "_Motion.npy"
    for n in (
        "Idle_Alert",
        "Idle_Battle",
        "Idle_Ready",
        "Standoff_Circle",
        "Standoff_Swing",
        "WalkForward01",
        "WalkBackward01",
        "WalkRight01",
        "Atk_Stab",
        "Atk_SlashDown",
        "Atk_SlashLeft",
        "Atk_SlashRight",
        "Atk_SlashUp",
        "Counter_Atk01",
        "Sword_ParryUp",
        "Shield_BlockUp",
    )
)


def bout(sport: str, round_s: float, iterations: int = 6000, num_envs: int = 32) -> TrainConfig:
    """Self-play of one shared policy, latest against latest, sized for a CPU: ``num_envs`` bouts
    x 2 players x horizon 8 per iteration, 256-256 networks, the paper's γ 0.99 and λ 0.95, one
    objective per reward term (critic head, PopArt, standardised advantage; ω below), penalties
    paid by the task (no ``terminate_reward``; the value after a bout's end is 0). 240 Hz physics, 30 Hz
    control. The policy is the learner's Gaussian MLP, so what this learns is reach and contact,
    not boxing style (the paper's mixture of experts with imitation pretraining:
    `boxing/selfplay_moe`).

    Departures from the paper, measured on the first CPU run (2M samples, paper weights, feet-only
    contacts, lr 1e-5): bouts ended after 0.4 s on average, every one by a fall, r_close did not
    rise (0.28 -> 0.25) and the energy term (-0.2 per step at weight 0.001: our 28-DoF PD
    character's joint-velocity changes, with σ = e^-2.5 exploration, sit far above the dead zone)
    outweighed closeness and facing (+0.1), so surviving was worth less than the fall penalty
    spread over the bout. Here: shins may touch the ground (the authors' code), exploration
    σ = e^-3, and the multi-objective learner instead of the paper's sum: in
    the sum (weights 1 / 0.2 / 0.05 / 0.001 / 30) the damage term's ±200 N at a 4% hit rate has a
    spread ~1000x the closeness signal, which zero-sum self-play averages away while its noise
    stays. ω (boxing): match 0.4, close 0.25, facing 0.1, energy 0.05, penalty 0.2; fencing
    match 0.5, close 0.3, penalty 0.2. The paper's form: ``ppo.multi_objective=false`` with
    ``env.task.boxing.weights=1,0.2,0.05,0.001,30``. The actor's lr is the paper's 1e-5 (3e-5
    with these standardised advantages gave PPO KL steps of 0.2-24).

    The round, ``round_s``, becomes ``env.episode_steps`` at the control rate: the one time limit
    that training truncates bouts at and ``python -m jaxmotion.eval`` plays bouts to."""
    from jaxmotion.physics.arena import ArenaConfig
    from jaxmotion.physics.sim import PhysicsConfig
    from jaxmotion.tasks import BoxingConfig

    fencing = sport == "fencing"
    from jaxmotion.tasks import FencingConfig

    task = TaskConfig(
        name=sport,
        boxing=BoxingConfig(weights=(0.4, 0.25, 0.1, 0.05, 0.2)),
        fencing=FencingConfig(weights=(0.5, 0.3, 0.2)),
    )
    physics = PhysicsConfig(sim_hz=240.0, sword_shield=fencing)
    env = EnvConfig(
        physics=physics,
        init_motions=FENCING_CLIPS if fencing else BOXING_CLIPS,
        groups=(),
        players=2,
        arena=ArenaConfig(sport=sport),
        task=task,
        policy_frames=1,
        allowed_contacts=("right_foot", "left_foot", "right_shin", "left_shin"),
        episode_steps=int(round(round_s * physics.control_hz)),
    )
    return TrainConfig(
        env=env,
        net=NetConfig(policy_hidden=(256, 256), critic_hidden=(256, 256), state_dependent_std=False, init_log_std=-3.0),
        ppo=PPOConfig(
            num_envs=num_envs,
            horizon=8,
            minibatch_size=128,
            epochs=5,
            gamma=0.99,
            lam=0.95,
            actor_lr=1e-5,
            critic_lr=1e-4,
            multi_objective=True,
            terminate_reward=None,
            absorbing_termination=False,
        ),
        iterations=iterations,
        chunk=10,
        eval_every=0,
    )
