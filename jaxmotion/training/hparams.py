"""A run's settings: network sizes, PPO, the discriminators, and ``TrainConfig`` holding them with
the environment and the run settings (``learner.py`` re-exports it).

Every field declares its range (``config.checks``); the rules between fields are
``TrainConfig.rules``, checked against the scene the config describes (``Scene.of_config``) when
a config is made, and against the environment itself when a learner is built (``Scene.of_env``).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Iterator
from typing import Annotated, Literal

from jaxmotion.algos import disc as D
from jaxmotion.config.checks import AllowInf, Count, Min, NonNegative, Positive, Problem, Range
from jaxmotion.config.errors import ConfigError
from jaxmotion.envs.humanoid import EnvConfig
from jaxmotion.tasks import TASKS, Task


@dataclasses.dataclass(frozen=True)
class NetConfig:
    """Network sizes (defaults: the authors' code, minus the GRU)."""

    policy_hidden: Annotated[tuple[int, ...], Min(1)] = (1024, 512)
    critic_hidden: Annotated[tuple[int, ...], Min(1)] = (1024, 512)
    activation: Literal["relu", "relu6", "tanh", "elu"] = "relu6"
    """One of ``nets.networks.ACTIVATIONS``."""
    state_dependent_std: bool = True
    init_log_std: float = -3.0
    """Initial log σ of the Gaussian policy (the paper's code starts at -3)."""
    critic_hidden_init: NonNegative = 0.0
    """0: the critic's hidden weights start at PyTorch's default U(+-1/sqrt(fan_in)), like the
    policy's; > 0: at U(+-critic_hidden_init) (the authors' code: 1e-4, as its heads)."""
    disc_hidden: Annotated[tuple[int, ...], Min(1)] = (256, 128)
    disc_hidden_gain: Positive = 1.0
    """Orthogonal gain of the discriminators' hidden layers (the authors' code: sqrt(2))."""
    disc_heads: Count = 32
    """Heads per discriminator ensemble (N in the paper)."""
    meta_weight_bias: float = 3.0
    """Incremental learning: initial bias of the sigmoid meta-weight head (3: w = 0.95, so the
    new policy starts as the meta policy; ``training/meta.py``)."""
    composer: Literal["product", "sum"] = "product"
    """With ``TrainConfig.primitives``: how the composer combines them (``nets/composer.py``):
    'product' (the paper's multiplicative Gaussian product) or 'sum' (the authors' code: a weighted
    sum of the means, fixed sigma exp(init_log_std)). The composer's MLP is ``policy_hidden``."""
    policy: Literal["mlp", "moe"] = "mlp"
    """The policy, when it builds on nothing frozen (``nets.policies.make_policy``): 'mlp' the
    Gaussian MLP of ``policy_hidden``; 'moe' Won et al. 2021's mixture of ``experts`` motor experts
    (``expert_hidden``, reading the body state only) gated by an encoder (``encoder_hidden``, the
    whole observation) whose weights are smoothed with ``gate_alpha`` (``nets/moe.py``)."""
    experts: Count = 8
    """Experts of the 'moe' policy (the paper: 8 for boxing, 4 for fencing)."""
    gate_alpha: Annotated[float, Range(0, 1, hi_open=True)] = 0.9
    """The 'moe' gate's smoothing: omega_hat_t = (1 - alpha) omega_t + alpha omega_hat_{t-1}."""
    expert_hidden: Annotated[tuple[int, ...], Min(1)] = (64, 64)
    encoder_hidden: Annotated[tuple[int, ...], Min(1)] = (128, 128)
    encoder: Literal["mlp", "lstm"] = "mlp"
    """The 'moe' gate's encoder: 'mlp' (the paper's fencing and imitation encoders) or 'lstm' (its
    boxing encoder: an LSTM of ``encoder_hidden[0]`` units, then dense layers of the rest; the
    LSTM state rides in the rollout with the gate's, one step of gradient, no BPTT)."""


@dataclasses.dataclass(frozen=True)
class PPOConfig:
    """PPO with multiple objectives (defaults: the paper's experiments)."""

    num_envs: Count = 512
    """Environments stepped in parallel (their states must fit in memory: ``Learner`` checks)."""
    horizon: Count = 8
    minibatch_size: Count = 256
    """Samples per PPO minibatch; it must divide ``samples_per_iteration``."""
    epochs: Count = 5
    gamma: Annotated[float, Range(0, 1, hi_open=True)] = 0.95
    lam: Annotated[float, Range(0, 1)] = 0.95
    clip_eps: Positive = 0.2
    max_grad_norm: Annotated[float, Min(0, open=True), AllowInf()] = 1.0
    """Global gradient-norm clip (inf: none)."""
    actor_lr: Positive = 5e-6
    critic_lr: Positive = 1e-4
    meta_weight_lr: NonNegative = 0.0
    """Incremental learning: Adam's learning rate for the meta-weight head w (0: ``actor_lr``). At
    5e-6 the sigmoid head stays where it starts (measured: w 0.94 -> 0.94 over 7M samples)."""
    value_coef: NonNegative = 0.5
    entropy_coef: NonNegative = 0.0
    multi_objective: bool = True
    """False: the w/o-MO ablation (rewards summed with ω, one critic head)."""
    popart: bool = True
    """False: the w/o-PopArt ablation (critic trained on raw returns)."""
    popart_beta: Annotated[float, Range(0, 1, lo_open=True)] = 0.1
    objective_weights: tuple[float, ...] = ()
    """ω per objective (groups, then the task's rewards), renormalised to sum to 1; empty: the
    groups' ``weight`` and the task's weights by the authors' rule (``tasks.combine_weights``).
    Non-empty: one non-negative number per objective, not all zero (``TrainConfig.rules``)."""
    per_objective_clip: bool = False
    """True: clip each ω_k Ā_k term separately (the authors' code) instead of Eq. 9."""
    terminate_reward: float | None = -2.0
    """Reward of every objective on a terminating step, and (absorbing) on every step after it.
    It must lie below the lowest reward an objective can pay (a discriminator's: -1 with the
    hinge loss, 0 with lsgan or bce), or a policy whose rewards sit at that floor loses nothing
    by falling: with -1, a saturated hinge discriminator made the fall's value -1/(1-gamma) = -20
    equal to staying up (measured). The authors' code uses -1 with a value of 0 after the fall.
    None: the step keeps its rewards (a task that pays its own penalties, as the two-player
    sports do)."""
    absorbing_termination: bool = True
    """True: a fall is an absorbing state that keeps paying ``terminate_reward`` (its value is
    ``terminate_reward / (1 - gamma)``), so with ``terminate_reward`` below every reward a fall
    always lowers the return. False: the authors' code (value 0 after the fall), which, with
    clipped discriminator rewards that sit near -1 early in training, makes an early fall the
    better deal; measured here, a policy trained that way learned to fall sooner."""
    obs_clip: Annotated[float, Min(0, open=True), AllowInf()] = 5.0
    """The normalised body-state features are clipped to +-obs_clip (inf: not clipped)."""
    normalize_goal: bool = False
    """Normalise (and clip) the task's goal features with the body state's running statistics
    too, as the tracker's authors normalise the whole observation; False: the goal features
    enter raw after the normalised body state (the composite-motion authors' code)."""


@dataclasses.dataclass(frozen=True)
class DiscConfig:
    """Discriminator ensembles: a prediction loss (``loss``) with gradient penalty.

    ``loss`` picks the discriminator's loss and the reward that goes with it (``algos.disc``),
    applied per head and averaged over heads; the gradient penalty (``gp_mode``, ``gp_weight``)
    is the same for all three:

    * 'hinge' (default): the paper's hinge loss (Xu et al. 2023, Eq. 2), reward the
      clipped logit, in [-1, 1] (Eq. 5).
    * 'lsgan': AMP's least-squares GAN (Peng et al. 2021, the paper), targets +1 / -1,
      reward max(0, 1 - (D - 1)^2 / 4), in [0, 1].
    * 'bce': binary cross-entropy on logits, as in AMP's isaacgym code that PHC (ZhengyiLuo/PHC)
      inherits; reward -log max(1 - sigmoid(D), 1e-4), in [0, log 1e4 = 9.21].
    """

    lr: Positive = 1e-5
    gp_weight: NonNegative = 10.0
    gp_mode: Literal["sum_heads", "per_head"] = "sum_heads"
    """'sum_heads' (the authors' code, default) or 'per_head' (paper Eq. 2). Measured on
    chest_open+squat: with 'per_head', 95% of the upper-body policy samples sat at the reward
    floor of -1 after 120 iterations (lower body 75%), a saturated discriminator that gives the
    policy no gradient; with 'sum_heads' 0%. Per head is also the costlier: its 32 input
    gradients come from ``networks.head_input_grad_sq_norms`` (the chain rule as matrix
    products)."""
    minibatch_size: Count = 256
    """Samples per discriminator minibatch; it must divide ``samples_per_iteration``."""
    loss: Literal["hinge", "lsgan", "bce"] = "hinge"
    """'hinge' (default), 'lsgan' or 'bce' (class docstring); it also sets the reward floor that
    ``ppo.terminate_reward`` must lie below (-1, 0, 0)."""

    def __post_init__(self):
        D.check_loss(self.loss)  # a DiscConfig made in Python fails at once (overrides: the Literal)


@dataclasses.dataclass(frozen=True)
class ProgressiveConfig:
    """Progressive primitives and their composer (PHC §3.2, ``training/progressive.py``): one
    command trains primitive 1 on every clip, primitive k from primitive k-1 on the clips k-1
    fails, each frozen when its tracking success stops rising, then a composer over them all."""

    primitives: Annotated[int, Min(0)] = 0
    """Primitives to train (at most; fewer when a stage leaves no failed clip); 0: a plain run."""
    stage_iterations: Count = 2000
    """At most this many iterations per primitive (a stage may stop earlier: ``patience``)."""
    patience: Count = 3
    """A primitive is frozen after this many mining passes without a rise in its success rate."""
    composer_iterations: Annotated[int, Min(0)] = 2000
    """Iterations of the composer over the primitives (0: no composer)."""
    recovery_iterations: Annotated[int, Min(0)] = 0
    """Iterations of the fail-state recovery primitive (PHC's P(F), ``tasks/recovery.py``), from
    the last imitation primitive, before the composer; 0: none. The imitation primitives train
    with ``env.task.track.recovery`` off; the recovery primitive and the composer with it on
    (the experiment's recovery settings otherwise)."""
    recovery_clips: tuple[str, ...] = ()
    """The recovery primitive's clips (the authors: their locomotion subset); empty: every clip."""


@dataclasses.dataclass(frozen=True)
class TrainConfig:
    """A complete experiment: environment, networks, algorithm and run settings."""

    env: EnvConfig = EnvConfig()
    net: NetConfig = NetConfig()
    ppo: PPOConfig = PPOConfig()
    disc: DiscConfig = DiscConfig()
    progressive: ProgressiveConfig = ProgressiveConfig()
    seed: Annotated[int, Range(0, 2**32 - 1)] = 0
    iterations: Annotated[int, Range(1, 2**31 - 1)] = 1000
    """Training iterations (each collects num_envs * horizon samples); a multiple of ``chunk``
    (the state counts them in int32)."""
    chunk: Count = 10
    """Iterations per compiled call; Python logs and checkpoints between chunks."""
    checkpoint_every: Count = 10
    """Chunks between checkpoints."""
    resume: str = ""
    """A run folder to continue from its latest checkpoint."""
    init_from: str = ""
    """A run folder or ``pretrained/<name>`` entry whose parameters, optimiser and statistics (and
    iteration count) a new run starts from; ``iterations`` counts from that run's start."""
    eval_episodes: Count = 4
    eval_every: Annotated[int, Min(0)] = 0
    """Chunks between deterministic evaluations logged as ``eval/<group>/dtw_error_m`` (0: never)."""
    meta: str = ""
    """Incremental learning: a run folder (or a folder of runs: the newest) whose frozen policy
    is the meta policy (``training/meta.py``); empty: none."""
    primitives: tuple[str, ...] = ()
    """Run folders (or pretrained entries) of frozen policies that a composer weights
    (``training/primitives.py``, ``NetConfig.composer``); PPO trains only the composer."""
    player_policies: Literal["shared", "separate"] = "shared"
    """Two-player scenes: 'shared' (one policy, critic and normaliser act for both players, each
    player a sample of its own) or 'separate' (each player has its own policy, critic, PopArt,
    observation statistics and optimiser, trained on its own transitions only)."""
    opponent_pool: Annotated[int, Min(0)] = 0
    """Two-player self-play: snapshots of the shared policy kept as opponents (``pool.py``); 0: none."""
    opponent_share: Annotated[float, Range(0, 1)] = 0.25
    """With a pool: the share of bouts whose player 1 is a pool member (not trained on)."""
    opponent_every: Count = 100
    """With a pool: iterations between snapshots (the oldest replaced once the pool is full)."""
    decoder_from: str = ""
    """A run folder (or pretrained entry) of a 'moe' policy whose motor decoder (the experts and
    sigma) and body statistics this run's 'moe' policy starts from, with a new encoder: Won et
    al.'s transfer from imitation pretraining to a sport (``training/runs.transfer_decoder``)."""
    decoder_start: Annotated[int, Min(0)] = 0
    """A 'moe' policy's decoder stays frozen for its first ``decoder_start`` iterations, the encoder
    learning alone (the paper: 300-500 after a transfer); 0: it learns from the start."""
    decoder_every: Annotated[int, Min(0)] = 0
    """After ``decoder_start``: turns of this many iterations, end to end, then encoder only, and
    so on (the paper: 50); 0: end to end throughout (``nets.moe.decoder_learns``)."""
    hard_negatives_every: Annotated[int, Min(0)] = 0
    """Tracking: every this many chunks, run every clip once from t = 0 and reset to the clips it
    failed more often (``evaluation.tracking.MINING``); 0: never."""

    def __post_init__(self):
        if self.player_policies not in ("shared", "separate"):  # made in Python (overrides: the Literal)
            raise ConfigError(f"player_policies must be 'shared' or 'separate', got {self.player_policies!r}")

    @property
    def samples_per_iteration(self) -> int:
        """Samples per iteration: every player of every environment for ``horizon`` steps."""
        return self.ppo.num_envs * self.ppo.horizon * self.env.players

    def checks(self) -> list[Problem]:
        """The rules between settings in the scene this config describes (``config.checks``)."""
        return self.rules(Scene.of_config(self.env))

    def rules(self, scene: Scene) -> list[Problem]:
        """The rules between settings for a learner in ``scene``: the run's length, the players'
        policies, the opponent pool, minibatches, objective weights, the fall's value, mining."""
        return [p for rule in RULES for p in rule(self, scene)]


@dataclasses.dataclass(frozen=True)
class Scene:
    """What the rules between settings need to know of the environment: taken from the config
    (its task's class) before the environment exists, from the environment once it does (an
    environment passed to the learner may be another than the config would build)."""

    players: int
    objectives: tuple[str, ...]
    """Group names, then the task's reward names: one objective each."""
    discriminators: bool
    task_min_reward: float
    mines_clips: bool

    @staticmethod
    def of_config(env: EnvConfig) -> Scene:
        task = TASKS.get(env.task.name, Task)
        groups = tuple(g.name for g in env.groups)
        return Scene(env.players, groups + tuple(task.reward_names), bool(groups), task.min_reward, task.mines_clips)

    @staticmethod
    def of_env(env, cfg: EnvConfig) -> Scene:
        """The scene of a built environment (``cfg``: the settings it was built for)."""
        task = env.task
        objectives = tuple(g.name for g in cfg.groups) + tuple(task.reward_names)
        return Scene(
            getattr(env, "players", 1),
            objectives,
            bool(env.disc_obs_sizes()),
            task.min_reward,
            getattr(task, "mines_clips", False),
        )


def pool_bouts(cfg: TrainConfig) -> int:
    """Bouts whose player 1 is a pool member (``pool.OpponentPool``)."""
    return int(round(cfg.opponent_share * cfg.ppo.num_envs))


def _run_length(cfg: TrainConfig, scene: Scene) -> Iterator[Problem]:
    if cfg.iterations % cfg.chunk:
        yield Problem(
            "iterations", f"must be a multiple of chunk ({cfg.chunk}): each compiled call runs chunk iterations"
        )


def _player_policies(cfg: TrainConfig, scene: Scene) -> Iterator[Problem]:
    if cfg.player_policies == "separate" and scene.players < 2:
        yield Problem("player_policies", "'separate' needs a two-player scene (env.players=2)")
    if cfg.player_policies == "separate" and cfg.meta:
        yield Problem("player_policies", f"'separate' takes no meta policy (meta={cfg.meta})")
    if cfg.player_policies == "separate" and cfg.primitives:
        yield Problem("player_policies", "'separate' takes no primitives")
    if cfg.meta and cfg.primitives:
        yield Problem("primitives", f"a composer of primitives takes no meta policy (meta={cfg.meta})")


def _mixture(cfg: TrainConfig, scene: Scene) -> Iterator[Problem]:
    moe = cfg.net.policy == "moe"
    if moe and (cfg.meta or cfg.primitives):
        yield Problem("net.policy", "'moe' builds on nothing frozen: it takes no meta policy or primitives")
    if moe and cfg.opponent_pool:
        yield Problem("opponent_pool", "the pool's opponents act without a recurrent gate: use net.policy=mlp")
    if not moe:
        for name in ("decoder_from", "decoder_start", "decoder_every"):
            if getattr(cfg, name):
                yield Problem(name, "applies to a mixture of experts (net.policy=moe)")


def _opponent_pool(cfg: TrainConfig, scene: Scene) -> Iterator[Problem]:
    if not cfg.opponent_pool:
        return
    if cfg.player_policies != "shared":
        yield Problem("opponent_pool", "needs player_policies=shared")
    if scene.players != 2:
        yield Problem("opponent_pool", f"needs a two-player scene (env.players=2), not {scene.players} player(s)")
    bouts, n = pool_bouts(cfg), cfg.ppo.num_envs
    if not 1 <= bouts < n:
        yield Problem(
            "opponent_share",
            f"gives {bouts} pool bouts of ppo.num_envs={n}: it must give at least one and leave at least one "
            "latest-vs-latest bout",
        )


def _minibatches(cfg: TrainConfig, scene: Scene) -> Iterator[Problem]:
    pc, mb_disc = cfg.ppo, cfg.disc.minibatch_size if scene.discriminators else 1
    n = pc.num_envs * pc.horizon * scene.players
    if cfg.opponent_pool and scene.players == 2:  # the pool's samples are left out, minibatches drop the rest
        bouts = pool_bouts(cfg)
        n = pc.horizon * (pc.num_envs * scene.players - bouts)
        if 1 <= bouts < pc.num_envs and n < max(pc.minibatch_size, mb_disc):
            yield Problem("ppo.minibatch_size", f"the learner's {n} samples per iteration are fewer than a minibatch")
        return
    what = (
        f"the {n} samples per iteration (ppo.num_envs*ppo.horizon*players = {pc.num_envs}*{pc.horizon}*{scene.players})"
    )
    if n % pc.minibatch_size:
        yield Problem("ppo.minibatch_size", f"must divide {what}")
    if n % mb_disc:
        yield Problem("disc.minibatch_size", f"must divide {what}")


def _objective_weights(cfg: TrainConfig, scene: Scene) -> Iterator[Problem]:
    w, k = cfg.ppo.objective_weights, len(scene.objectives)
    if w and (len(w) != k or min(w) < 0 or sum(w) <= 0):
        yield Problem(
            "ppo.objective_weights",
            f"objective_weights must be {k} non-negative numbers, not all 0 (for {', '.join(scene.objectives)})",
        )


def _fall_value(cfg: TrainConfig, scene: Scene) -> Iterator[Problem]:
    pc = cfg.ppo
    if not pc.absorbing_termination:
        return
    if pc.terminate_reward is None:
        yield Problem("ppo.absorbing_termination", "needs a ppo.terminate_reward (it is none)")
        return
    low = min([D.MIN_REWARD[cfg.disc.loss]] * scene.discriminators + [scene.task_min_reward])
    if not pc.terminate_reward < low:
        yield Problem(
            "ppo.terminate_reward",
            f"must be below the lowest reward an objective pays ({low:g}); otherwise a fall is worth as much "
            "as staying up with every reward at its floor",
        )


def _mining(cfg: TrainConfig, scene: Scene) -> Iterator[Problem]:
    if cfg.hard_negatives_every and not scene.mines_clips:
        yield Problem(
            "hard_negatives_every",
            f"needs a task that resets to the clips it tracks (env.task.name=track), not {cfg.env.task.name!r}",
        )


def progressive_problems(cfg: TrainConfig, scene: Scene | None = None) -> Iterator[Problem]:
    """What keeps ``cfg``'s progressive pipeline from running (checked before its first stage)."""
    pc = cfg.progressive
    if not pc.primitives:
        return
    if not cfg.hard_negatives_every:
        yield Problem(
            "progressive.primitives",
            "needs hard-negative mining (hard_negatives_every > 0): it finds each stage's clips",
        )
    if pc.recovery_iterations and cfg.env.task.name != "track":
        yield Problem("progressive.recovery_iterations", "a recovery primitive is a tracker's (env.task.name=track)")
    for key in ("stage_iterations", "composer_iterations", "recovery_iterations"):
        if getattr(pc, key) % cfg.chunk:
            yield Problem(f"progressive.{key}", f"must be a multiple of chunk ({cfg.chunk})")
    if cfg.primitives or cfg.meta:
        yield Problem(
            "progressive.primitives", "a progressive pipeline makes its own primitives (no primitives= or meta=)"
        )


RULES = (
    progressive_problems,
    _run_length,
    _player_policies,
    _opponent_pool,
    _mixture,
    _minibatches,
    _objective_weights,
    _fall_value,
    _mining,
)
"""``TrainConfig.rules``, in order: each yields the ``Problem``s it finds."""
