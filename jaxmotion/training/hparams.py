"""The learner's hyperparameters: network sizes, PPO and the discriminators (``learner.TrainConfig``
holds them with the environment and the run settings)."""

from __future__ import annotations

import dataclasses

from jaxmotion.algos import disc as D


@dataclasses.dataclass(frozen=True)
class NetConfig:
    """Network sizes (defaults: the authors' code, minus the GRU)."""

    policy_hidden: tuple[int, ...] = (1024, 512)
    critic_hidden: tuple[int, ...] = (1024, 512)
    activation: str = "relu6"
    state_dependent_std: bool = True
    init_log_std: float = -3.0
    """Initial log σ of the Gaussian policy (the paper's code starts at -3)."""
    critic_hidden_init: float = 0.0
    """0: the critic's hidden weights start at PyTorch's default U(+-1/sqrt(fan_in)), like the
    policy's; > 0: at U(+-critic_hidden_init) (the authors' code: 1e-4, as its heads)."""
    disc_hidden: tuple[int, ...] = (256, 128)
    disc_hidden_gain: float = 1.0
    """Orthogonal gain of the discriminators' hidden layers (the authors' code: sqrt(2))."""
    disc_heads: int = 32
    """Heads per discriminator ensemble (N in the paper)."""
    meta_weight_bias: float = 3.0
    """Incremental learning: initial bias of the sigmoid meta-weight head (3: w = 0.95, so the
    new policy starts as the meta policy; ``training/meta.py``)."""


@dataclasses.dataclass(frozen=True)
class PPOConfig:
    """PPO with multiple objectives (defaults: the paper's experiments)."""

    num_envs: int = 512
    horizon: int = 8
    minibatch_size: int = 256
    epochs: int = 5
    gamma: float = 0.95
    lam: float = 0.95
    clip_eps: float = 0.2
    max_grad_norm: float = 1.0
    actor_lr: float = 5e-6
    critic_lr: float = 1e-4
    meta_weight_lr: float = 0.0
    """Incremental learning: Adam's learning rate for the meta-weight head w (0: ``actor_lr``). At
    5e-6 the sigmoid head stays where it starts (measured: w 0.94 -> 0.94 over 7M samples)."""
    value_coef: float = 0.5
    entropy_coef: float = 0.0
    multi_objective: bool = True
    """False: the w/o-MO ablation (rewards summed with ω, one critic head)."""
    popart: bool = True
    """False: the w/o-PopArt ablation (critic trained on raw returns)."""
    popart_beta: float = 0.1
    objective_weights: tuple[float, ...] = ()
    """ω per objective (groups, then the task's rewards), renormalised to sum to 1; empty: the
    groups' ``weight`` and the task's weights by the authors' rule (``tasks.combine_weights``)."""
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
    obs_clip: float = 5.0


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

    lr: float = 1e-5
    gp_weight: float = 10.0
    gp_mode: str = "sum_heads"
    """'sum_heads' (the authors' code, default) or 'per_head' (paper Eq. 2). Measured on
    chest_open+squat: with 'per_head', 95% of the upper-body policy samples sat at the reward
    floor of -1 after 120 iterations (lower body 75%), a saturated discriminator that gives the
    policy no gradient; with 'sum_heads' 0%. Per head is also the costlier: its 32 input
    gradients come from ``networks.head_input_grad_sq_norms`` (the chain rule as matrix
    products)."""
    minibatch_size: int = 256
    loss: str = "hinge"
    """'hinge' (default), 'lsgan' or 'bce' (class docstring); it also sets the reward floor that
    ``ppo.terminate_reward`` must lie below (-1, 0, 0)."""

    def __post_init__(self):
        D.check_loss(self.loss)
