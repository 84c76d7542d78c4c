"""MJX physics for one character: model settings and the PD servo stepped in a scan.

Settings, and why (numbers measured on a 2-core CPU, see DESIGN.md):

* ``implicitfast`` integrator: the PD damping term (an actuator bias ``-kd*qdot``) is then
  integrated implicitly, which holds a standing humanoid at 120 Hz where explicit PD drops it.
* Newton solver, 4 iterations, 8 line-search iterations: Isaac Gym's TGS runs 4 position
  iterations; Newton converges in few iterations and keeps contacts stable at this budget.
* float32 everywhere (MJX default): float64 doubles memory traffic for no visible gain here.
* Floor-only contacts (``physics/character.py``): 34 candidates instead of 175.
* ``eulerdamp`` disabled: with ``implicitfast`` the joint damping is already implicit.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Annotated, Literal

import jax
import jax.numpy as jnp
import mujoco
from mujoco import mjx

from jaxmotion.config.checks import Min, Problem
from jaxmotion.config.errors import ConfigError
from jaxmotion.physics import backends
from jaxmotion.physics.character import Character
from jaxmotion.physics.props import PropConfig, prop_channels, scene_mjcf


@dataclasses.dataclass(frozen=True)
class PhysicsConfig:
    """How the character is simulated."""

    sim_hz: Annotated[float, Min(0, open=True)] = 120.0
    """Physics rate; one MJX step is ``1/sim_hz`` s."""
    control_hz: Annotated[float, Min(0, open=True)] = 30.0
    """Policy rate; each control step runs ``sim_hz / control_hz`` physics substeps (a whole number)."""
    solver_iterations: Annotated[int, Min(1)] = 16
    """Cap on the contact solver's (Newton) iterations per physics step; it stops earlier once
    converged. At 4 (MJX's speed setting) the unconverged foot contacts threw the ankles past
    100 rad/s in 0.17% of control steps of a squatting policy (reset as unstable physics, i.e.
    a fall in training and in evaluation); re-simulated with 50 iterations or dt/8 those steps
    peak at 7-34 rad/s. At 8 or more: none in 38k steps, for ~20% of the env-step throughput."""
    ls_iterations: Annotated[int, Min(1)] = 16
    sword_shield: bool = False
    """Use the 17-body sword-and-shield character (31 DoF) instead of the 15-body humanoid."""
    racket: bool = False
    """With ``sword_shield``: a tennis racket instead of the sword, and no shield
    (``physics/character.py``)."""
    props: tuple[PropConfig, ...] = ()
    """Free bodies (balls) in the scene after the character, moved by the task
    (``physics/props.py``)."""
    impl: Literal["auto", "jax", "warp"] = "auto"
    """MJX implementation: 'jax', 'warp' (NVIDIA GPUs only) or 'auto' (warp where available)."""
    backend: Literal["auto", "mjx", "mujoco"] = "auto"
    """Physics engine: 'mjx', 'mujoco' (MuJoCo C through a host callback inside the compiled
    loop, threaded over the batch) or 'auto' (MuJoCo C on a CPU, MJX on an accelerator); see
    ``physics/backends.py``."""
    threads: Annotated[int, Min(0)] = 0
    """Threads of the MuJoCo C backend's pool (0: one per CPU core)."""
    servo_damping: Literal["actuator", "joint"] = "actuator"
    """Where the PD servo's damping ``-kd*qdot`` lives. 'actuator' (every run before 2026-12-05):
    in the actuator's affine bias, clipped together with ``kp*(target - q)`` at the torque limit.
    MuJoCo C then leaves a clipped actuator out of the implicit integration (its force no longer
    depends on qdot) while MJX keeps it: from a tracker's reset state with 14 of 28 actuators at
    their limit, one 120-Hz substep gave an ankle 38 rad/s in C and 2.4 rad/s in MJX, and the same
    trained tracker drew 3-4x the servo power in C (1808 vs 628 W). 'joint': ``kd`` as joint
    damping (implicit and never clipped), the actuator clipping only ``kp*(target - q)``; the two
    engines then agree (``tests/test_backends.py``)."""

    def __post_init__(self):
        if self.servo_damping not in ("actuator", "joint"):  # made in Python (overrides: the Literal)
            raise ConfigError(f"servo_damping must be 'actuator' or 'joint', got {self.servo_damping!r}")

    def checks(self) -> list[Problem]:
        """The rules between the physics settings (``config.checks``)."""
        out = []
        if not self._whole_substeps():
            out.append(Problem("sim_hz", f"must be a multiple of control_hz ({self.control_hz:g})"))
        if self.racket and not self.sword_shield:
            out.append(Problem("racket", "needs the sword-and-shield character (its 3-DoF wrist): sword_shield=true"))
        names = [p.name for p in self.props]
        if len(set(names)) < len(names):
            out.append(Problem("props", "must have different names"))
        return out

    def _whole_substeps(self) -> bool:
        n = self.sim_hz / self.control_hz
        return abs(n - round(n)) <= 1e-6 and n >= 1

    @property
    def substeps(self) -> int:
        if not self._whole_substeps():
            raise ConfigError(f"sim_hz ({self.sim_hz}) must be a multiple of control_hz ({self.control_hz})")
        return int(round(self.sim_hz / self.control_hz))

    @property
    def control_dt(self) -> float:
        return 1.0 / self.control_hz


def scene_xml(cfg: PhysicsConfig, floor: bool = True) -> str:
    """The MJCF of the scene ``cfg`` describes: the character, its racket and the props."""
    return scene_mjcf(cfg.sword_shield, cfg.racket, cfg.props, floor=floor)


def character_xml(cfg: PhysicsConfig, floor: bool = True) -> str:
    """The MJCF of the character alone (its racket included, no props): what the video draws."""
    return scene_mjcf(cfg.sword_shield, cfg.racket, (), floor=floor)


def mj_model(cfg: PhysicsConfig) -> mujoco.MjModel:
    """The MuJoCo C model of the scene with the solver settings of ``cfg``."""
    return apply_settings(mujoco.MjModel.from_xml_string(scene_xml(cfg)), cfg)


def apply_settings(m: mujoco.MjModel, cfg: PhysicsConfig) -> mujoco.MjModel:
    """``m`` (edited in place) with the rate, solver budget and servo damping of ``cfg``; every
    scene, one character's or a two-player arena, goes through here."""
    m.opt.timestep = 1.0 / cfg.sim_hz
    m.opt.iterations = cfg.solver_iterations
    m.opt.ls_iterations = cfg.ls_iterations
    if cfg.servo_damping == "joint":  # kd leaves the clipped actuator for the joint (never clipped)
        dof = m.jnt_dofadr[m.actuator_trnid[:, 0]]
        m.dof_damping[dof] = -m.actuator_biasprm[:, 2]
        m.actuator_biasprm[:, 2] = 0.0
    return m


def _impl(cfg: PhysicsConfig) -> str:
    if backends.resolve_backend(cfg.backend) == "mujoco":
        return "jax"  # MJX only computes kinematics for the observations then
    if cfg.impl != "auto":
        return cfg.impl
    if jax.default_backend() == "gpu":
        try:
            import mujoco_warp  # noqa: F401

            return "warp"
        except ImportError:
            pass
    return "jax"


@functools.lru_cache(maxsize=8)
def mjx_model(cfg: PhysicsConfig) -> mjx.Model:
    """The MJX model (device arrays) for ``cfg``; cached because it is immutable."""
    return mjx.put_model(mj_model(cfg), impl=_impl(cfg))


@functools.lru_cache(maxsize=8)
def physics(cfg: PhysicsConfig):
    """The physics backend object of ``cfg`` (``backends.MJXPhysics`` or ``MujocoPhysics``)."""
    m = mj_model(cfg)
    return backends.make_physics(
        cfg.backend,
        m,
        scene_xml(cfg),
        mjx_model(cfg),
        cfg.substeps,
        cfg.threads or None,
        channels=prop_channels(m, cfg.props),
    )


def pd_step(model: mjx.Model, data: mjx.Data, target: jax.Array, substeps: int) -> mjx.Data:
    """Holds ``target`` joint positions [n_dof] with the PD servo for ``substeps`` MJX steps.

    The servo is the model's actuators: torque ``clip(kp*(target - q) - kd*qdot, ±max_torque)``,
    with the damping integrated implicitly by ``implicitfast``.
    """
    return backends.mjx_pd_step(model, data, target, substeps)


def pd_torque(
    ch: Character, q: jax.Array, qdot: jax.Array, target: jax.Array, servo_damping: str = "actuator"
) -> jax.Array:
    """The servo's torque as an explicit formula (for tests and analysis) [.., n_dof]: the
    actuator's and, with ``servo_damping='joint'``, the joint damping's (``PhysicsConfig``)."""
    lim = jnp.asarray(ch.max_torque)
    damping = jnp.asarray(ch.kd) * qdot
    if servo_damping == "joint":
        return jnp.clip(jnp.asarray(ch.kp) * (target - q), -lim, lim) - damping
    return jnp.clip(jnp.asarray(ch.kp) * (target - q) - damping, -lim, lim)
