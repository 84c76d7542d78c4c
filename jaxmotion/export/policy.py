"""A trained policy as one function of what a plain MuJoCo simulation provides.

``policy_function(learner, ts)`` returns ``(fn, layout)``: ``fn`` maps the last F states of the
character (``qpos`` [F, nq], ``qvel`` [F, nv], oldest first) and, for a tracker, the reference's
next frame (``ref_qpos`` [nq], ``ref_qvel`` [nv]) to the PD targets [n_dof] the environment would
write as the actuators' controls. Inside: forward kinematics to link frames (``physics/fk.py``, as
``HumanoidEnv.frames_of``), the policy observation (``motion/observations.py``), the task's goal
features, the observation normaliser, the policy's mean (deterministic) and the PD target formula
(``HumanoidEnv.pd_target``, with the tracker's residual base where it has one). Everything is
float32, one character (no batch axis).

The reference is given as generalised coordinates rather than link frames: a user of plain MuJoCo
holds clips as ``qpos``/``qvel``, and jaxmotion's tracker makes its reference link frames by the
same forward kinematics of the same coordinates (``tasks/track.py``), so nothing is lost.

Only plain Gaussian policies of one player on the ``imitate`` and ``track`` tasks are exported
(``unsupported``): composed, meta and two-player policies, and tasks whose goal state lives
inside the task (targets, balls), are not yet.
"""

from __future__ import annotations

import dataclasses
import xml.etree.ElementTree as ET
from collections.abc import Callable

import jax
import jax.numpy as jnp

from jaxmotion.config.errors import JaxmotionError
from jaxmotion.envs.humanoid import safe_action
from jaxmotion.motion import observations as O
from jaxmotion.nets.policies import GaussianPolicy
from jaxmotion.physics import sim

TASKS = ("imitate", "track")
"""Tasks whose goal inputs are exported (none, or the tracker's reference frame)."""


class ExportError(JaxmotionError):
    """A run whose policy cannot be exported (yet)."""


@dataclasses.dataclass(frozen=True)
class Layout:
    """The exported function's inputs and output: (name, shape) pairs, float32, in call order."""

    inputs: tuple[tuple[str, tuple[int, ...]], ...]
    outputs: tuple[tuple[str, tuple[int, ...]], ...]

    def specs(self) -> list[jax.ShapeDtypeStruct]:
        return [jax.ShapeDtypeStruct(s, jnp.float32) for _, s in self.inputs]

    @property
    def input_names(self) -> list[str]:
        return [n for n, _ in self.inputs]

    @property
    def output_names(self) -> list[str]:
        return [n for n, _ in self.outputs]


def unsupported(cfg) -> str | None:
    """Why the policy of a run with config ``cfg`` (a ``TrainConfig``) is not exported, or None;
    decided from the config alone, before anything is loaded."""
    if cfg.meta or cfg.primitives:
        return "composed and meta policies (meta=, primitives=) are not exported yet: only plain Gaussian policies"
    if cfg.env.players != 1 or cfg.player_policies != "shared":
        return "two-player policies are not exported yet: only one character's plain Gaussian policy"
    if cfg.env.task.name not in TASKS:
        return f"task {cfg.env.task.name!r} is not exported yet: its goal state lives in the task (only {TASKS})"
    if cfg.env.physics.props:
        return "scenes with props are not exported yet"
    return None


def residual(cfg) -> bool:
    """Whether the PD targets build on the reference's joint angles (a residual tracker)."""
    return cfg.env.task.name == "track" and cfg.env.task.track.residual


def layout_of(env, cfg) -> Layout:
    """The inputs and output of the exported function of a run (see the module docstring)."""
    f, nq, nv = env.cfg.policy_frames, env._nq, env._nv
    inputs = [("qpos", (f, nq)), ("qvel", (f, nv))]
    if cfg.env.task.name == "track":
        inputs += [("ref_qpos", (nq,)), ("ref_qvel", (nv,))]
    return Layout(inputs=tuple(inputs), outputs=(("pd_target", (env.action_size,)),))


def policy_function(learner, ts) -> tuple[Callable[..., jax.Array], Layout]:
    """(``fn(*inputs) -> pd_target [n_dof]``, its layout) of a learner and its restored state."""
    cfg = learner.cfg
    why = unsupported(cfg)
    if why is None and not isinstance(learner.policy, GaussianPolicy):
        why = f"a {type(learner.policy).__name__} is not exported yet: only plain Gaussian policies"
    if why:
        raise ExportError(why)
    env, f = learner.env, learner.env.cfg.policy_frames
    params = jax.tree.map(jnp.asarray, ts.policy_params)
    norm = jax.tree.map(jnp.asarray, ts.obs_norm)
    tracking = cfg.env.task.name == "track"

    def fn(qpos, qvel, ref_qpos=None, ref_qvel=None):
        hist = env.frames_of(qpos, qvel)
        last = jax.tree.map(lambda x: x[-1], hist)
        feats = [O.policy_obs(hist)]
        base = None
        if tracking:
            feats.append(env.task.features(env.frames_of(ref_qpos, ref_qvel), last))
            base = env.clip_dof(ref_qpos[7:]) if residual(cfg) else None
        # A batch of one: jax2onnx 0.13.0 lowers a matrix product of a vector to an ONNX Gemm,
        # which takes matrices only (onnxruntime refuses the model).
        obs = jnp.concatenate(feats)[None]
        mean, _ = learner.policy.dist(params, learner.normalize_obs(norm, obs), jnp.zeros((1, 0), jnp.float32))
        action, _ = safe_action(mean[0])
        return env.pd_target(action, base)

    assert f == layout_of(env, cfg).inputs[0][1][0]
    return fn, layout_of(env, cfg)


def scene_xml(pc: sim.PhysicsConfig) -> str:
    """The scene's MJCF with the rate, solver budget and servo damping of ``pc`` written into it:
    compiled, it is ``sim.mj_model(pc)`` (``sim.apply_settings``), so a user can simulate the
    policy's character without jaxmotion. The source's other numbers are kept as written
    (``MjSpec.to_xml`` would round them to 6 digits: joint ranges 4e-6 rad off)."""
    root = ET.fromstring(sim.scene_xml(pc))
    option = root.find("option")
    if option is None:
        option = ET.SubElement(root, "option")
    option.set("timestep", repr(1.0 / pc.sim_hz))
    option.set("iterations", str(pc.solver_iterations))
    option.set("ls_iterations", str(pc.ls_iterations))
    if pc.servo_damping == "joint":  # kd leaves the clipped actuator for the joint (never clipped)
        joints = {j.get("name"): j for j in root.iter("joint")}
        for a in root.find("actuator"):
            bias = a.get("biasprm").split()
            joints[a.get("joint")].set("damping", bias[2].lstrip("-"))
            a.set("biasprm", " ".join([*bias[:2], "0"]))
    return ET.tostring(root, encoding="unicode")


def sidecar(learner, layout: Layout, files: dict[str, str]) -> dict:
    """What a user needs besides the function to run it: rates, the actuators' order, the servo,
    the action-to-target formula, the input and output layout, and the files written with it."""
    env, pc = learner.env, learner.cfg.env.physics
    ch = env.character
    return {
        "format": "jaxmotion policy export 1",
        "task": learner.cfg.env.task.name,
        "residual": residual(learner.cfg),
        "control_hz": pc.control_hz,
        "sim_hz": pc.sim_hz,
        "substeps": pc.substeps,
        "policy_frames": env.cfg.policy_frames,
        "nq": env._nq,
        "nv": env._nv,
        "joints": list(ch.joint_names),
        "bodies": list(ch.body_names),
        "servo_damping": pc.servo_damping,
        "kp": [float(x) for x in ch.kp],
        "kd": [float(x) for x in ch.kd],
        "torque_limit": [float(x) for x in ch.max_torque],
        "action_scale": env.cfg.action_scale,
        "mid_range": [float(x) for x in env._mid],
        "half_range": [float(x) for x in env._half],
        "pd_target": (
            "clip(ref_qpos[7:], joint_range) + action_scale * action * half_range"
            if residual(learner.cfg)
            else "mid_range + action_scale * action * half_range"
        ),
        "inputs": [{"name": n, "shape": list(s), "dtype": "float32"} for n, s in layout.inputs],
        "outputs": [{"name": n, "shape": list(s), "dtype": "float32"} for n, s in layout.outputs],
        "files": files,
    }
