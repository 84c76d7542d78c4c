"""Policies that run without JAX (``jaxmotion/export``): the ONNX function equals the policy's PD
targets as the environment computes them, the sidecar and the scene say what a user needs, and the
check replays the shipped policy in plain MuJoCo in a process without JAX."""

from __future__ import annotations

import dataclasses
import json
from pathlib import Path

import jax
import jax.numpy as jnp
import mujoco
import numpy as np
import pytest

from conftest import REPO, jit_enabled
from jaxmotion import config as C
from jaxmotion.algos.normalizer import NormalizerState
from jaxmotion.envs.humanoid import EnvConfig, EnvState, GroupConfig, HumanoidEnv
from jaxmotion.export import cli
from jaxmotion.export import policy as P
from jaxmotion.motion import MotionLib, make_test_clip
from jaxmotion.physics import sim
from jaxmotion.tasks import TaskConfig
from jaxmotion.tasks.track import TrackConfig, TrackGoal
from jaxmotion.training import checkpoint as ckpt
from jaxmotion.training.learner import DiscConfig, Learner, NetConfig, PPOConfig, TrainConfig

ort = pytest.importorskip("onnxruntime")
pytest.importorskip("jax2onnx")

PRETRAINED = REPO / "pretrained" / "chest_open+squat_cpu"


def tiny_learner(task: str = "imitate", residual: bool = False, servo_damping: str = "actuator") -> Learner:
    """A learner of toy size on a synthetic clip: two body groups (as the composite runs) or a
    tracker; 16-unit networks, nothing loaded from disk."""
    lib = MotionLib.from_clips([make_test_clip(num_frames=31, yaw_rate=0.5)])
    groups = (GroupConfig(name="full", frames=2),)
    if task == "imitate":
        groups = (GroupConfig(name="upper", frames=3), GroupConfig(name="lower", frames=3))
    env_cfg = EnvConfig(
        physics=sim.PhysicsConfig(servo_damping=servo_damping),
        groups=groups,
        policy_frames=2,
        task=TaskConfig(name=task, track=TrackConfig(residual=residual)),
    )
    cfg = TrainConfig(
        env=env_cfg,
        net=NetConfig(policy_hidden=(16, 16), critic_hidden=(8,), disc_hidden=(8,), disc_heads=2),
        ppo=PPOConfig(num_envs=2, horizon=2, minibatch_size=4),
        disc=DiscConfig(minibatch_size=4),
    )
    libs = tuple(lib for _ in groups)
    return Learner(cfg, env=HumanoidEnv(env_cfg, motion_libs=libs, init_lib=lib))


def acting_state(learner: Learner, seed: int = 0):
    """Fresh policy parameters and observation statistics far from the identity (so the
    normaliser's part of the function is checked too)."""
    k_pol, k_mean, k_std = jax.random.split(jax.random.PRNGKey(seed), 3)
    d = learner.body_obs_size
    norm = NormalizerState(
        count=jnp.ones((), jnp.float32),
        mean=jax.random.normal(k_mean, (d,)) * 0.3,
        summed_variance=jnp.ones((d,)),
        std=jnp.exp(jax.random.normal(k_std, (d,)) * 0.5),
    )

    @dataclasses.dataclass(frozen=True)
    class Acting:
        policy_params: object
        obs_norm: NormalizerState
        meta: object = None

    return Acting(policy_params=learner.policy.init(k_pol), obs_norm=norm)


def random_states(env: HumanoidEnv, rng: np.random.Generator, frames: int) -> tuple[np.ndarray, np.ndarray]:
    """Valid states: root near standing height, a unit root quaternion, joint angles within
    their ranges, moderate velocities; [frames, nq], [frames, nv] float32."""
    lo, hi = np.asarray(env._lo), np.asarray(env._hi)
    qpos = np.zeros((frames, env._nq))
    qpos[:, :3] = rng.normal([0.0, 0.0, 0.9], [1.0, 1.0, 0.05], (frames, 3))
    quat = rng.normal(size=(frames, 4))
    qpos[:, 3:7] = quat / np.linalg.norm(quat, axis=-1, keepdims=True)
    qpos[:, 7:] = rng.uniform(lo, hi, (frames, len(lo)))
    qvel = rng.normal(0.0, 1.0, (frames, env._nv))
    return qpos.astype(np.float32), qvel.astype(np.float32)


def env_targets(learner: Learner, acting, qpos, qvel, goal=None) -> jax.Array:
    """The PD targets the environment writes at the state whose history is (qpos, qvel): its own
    observation, the learner's deterministic action and the env's PD formula."""
    env = learner.env
    hist = env.frames_of(jnp.asarray(qpos), jnp.asarray(qvel))
    state = EnvState(data=None, hist=hist, steps=jnp.zeros((), jnp.int32), rng=jax.random.PRNGKey(0), goal=goal)
    mean, _, _ = learner.act(acting, env.policy_obs(state)[None], None)
    return env.pd_target(mean[0], env.task.pd_base(goal))


def onnx_session(learner: Learner, acting, tmp_path: Path):
    fn, layout = P.policy_function(learner, acting)
    path = tmp_path / "policy.onnx"
    from jaxmotion.export.formats import write_onnx

    write_onnx(fn, layout, path)
    return ort.InferenceSession(str(path), providers=["CPUExecutionProvider"]), fn, layout


@pytest.mark.parametrize(
    "task,residual", [("imitate", False), ("track", False), ("track", True)], ids=["imitate", "track", "residual"]
)
def test_the_onnx_function_equals_the_environments_pd_targets(tmp_path, task, residual):
    learner = tiny_learner(task, residual)
    env, acting = learner.env, acting_state(learner)
    rng = np.random.default_rng(1)
    with jit_enabled():
        session, _, layout = onnx_session(learner, acting, tmp_path)
        assert [i.name for i in session.get_inputs()] == layout.input_names
        targets = jax.jit(lambda q, v, g: env_targets(learner, acting, q, v, g))
        for i in range(4):
            qpos, qvel = random_states(env, rng, env.cfg.policy_frames)
            feed = {"qpos": qpos, "qvel": qvel}
            goal = None
            if task == "track":
                goal = TrackGoal(clip=jnp.asarray(0, jnp.int32), time=jnp.asarray(0.1 * i, jnp.float32))
                ref_qpos, ref_qvel = env.task.reference_coords(goal, env.dt)
                feed.update(ref_qpos=np.asarray(ref_qpos, np.float32), ref_qvel=np.asarray(ref_qvel, np.float32))
            want = np.asarray(targets(qpos, qvel, goal))
            got = session.run(None, feed)[0]
            np.testing.assert_allclose(got, want, atol=1e-4, rtol=0)
            assert np.abs(got - np.asarray(env._mid)).max() > 1e-3  # a policy that moves the joints


def test_stablehlo_is_the_same_function(tmp_path):
    learner = tiny_learner("track", residual=True)
    acting = acting_state(learner)
    with jit_enabled():
        fn, layout = P.policy_function(learner, acting)
        from jaxmotion.export.formats import write_stablehlo

        write_stablehlo(fn, layout, tmp_path / "p.stablehlo")
        loaded = jax.export.deserialize((tmp_path / "p.stablehlo").read_bytes())
        args = [np.random.default_rng(2).normal(size=s).astype(np.float32) * 0.1 for _, s in layout.inputs]
        args[0][..., 3] = 1.0  # unit root quaternions
        np.testing.assert_allclose(loaded.call(*args), jax.jit(fn)(*args), atol=1e-6)


@pytest.mark.parametrize("servo_damping", ["actuator", "joint"])
def test_the_sidecar_and_the_scene_say_what_a_plain_simulation_needs(tmp_path, servo_damping):
    learner = tiny_learner("track", servo_damping=servo_damping)
    with jit_enabled():
        written = cli.export(learner, acting_state(learner), "onnx", tmp_path / "p.onnx")
    meta = json.loads(written["sidecar"].read_text())
    for key in (
        "control_hz",
        "sim_hz",
        "substeps",
        "joints",
        "kp",
        "kd",
        "torque_limit",
        "action_scale",
        "mid_range",
        "half_range",
        "policy_frames",
        "inputs",
        "outputs",
        "files",
    ):
        assert key in meta, key
    assert meta["substeps"] == 4 and meta["policy_frames"] == 2 and len(meta["joints"]) == 28
    assert [i["name"] for i in meta["inputs"]] == ["qpos", "qvel", "ref_qpos", "ref_qvel"]
    assert meta["inputs"][0]["shape"] == [2, 35] and meta["outputs"][0]["shape"] == [28]
    # The scene compiles to the model jaxmotion simulates, every number included.
    got = mujoco.MjModel.from_xml_path(str(tmp_path / meta["files"]["scene"]))
    want = sim.mj_model(learner.cfg.env.physics)
    assert got.opt.timestep == want.opt.timestep and got.opt.iterations == want.opt.iterations
    for field in (
        "dof_damping",
        "actuator_biasprm",
        "actuator_gainprm",
        "actuator_forcerange",
        "jnt_range",
        "body_mass",
    ):
        np.testing.assert_array_equal(getattr(got, field), getattr(want, field), err_msg=field)
    names = [got.actuator(i).name for i in range(got.nu)]
    assert names == meta["joints"]


def test_the_check_replays_the_pretrained_policy_without_jax(tmp_path, data_dir, capsys, monkeypatch):
    monkeypatch.setenv("JAXMOTION_DATA", str(data_dir))
    out = tmp_path / "policy.onnx"
    with jit_enabled():
        code = cli.main([str(PRETRAINED), "--out", str(out), "--check", "--steps", "30"])
    text = capsys.readouterr().out
    assert code == 0, text
    assert "jax not imported" in text and "stayed up" in text and "30 of 30" in text
    assert out.is_file() and out.with_suffix(".json").is_file() and out.with_suffix(".xml").is_file()


def _one_line(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert err.startswith("error: ") and len(err.splitlines()) == 1, err
    return err


def test_a_folder_that_is_no_run_is_one_line(tmp_path, capsys):
    assert cli.main([str(tmp_path), "--out", str(tmp_path / "p.onnx")]) == 2
    assert str(tmp_path) in _one_line(capsys)


def test_composed_meta_and_two_player_policies_are_refused_in_one_line(tmp_path, capsys):
    base = C.load_experiment("smoke")
    for name, cfg in {
        "meta": dataclasses.replace(base, meta="runs/some/meta"),
        "goal task": dataclasses.replace(
            base,
            env=dataclasses.replace(base.env, task=TaskConfig(name="location")),
            ppo=dataclasses.replace(base.ppo, objective_weights=()),
        ),
    }.items():
        ckpt.write_config(tmp_path / name, "x", cfg)
        assert cli.main([str(tmp_path / name), "--out", str(tmp_path / "p.onnx")]) == 2
        assert "not exported yet" in _one_line(capsys)


def test_an_output_that_cannot_be_written_is_one_line(tmp_path, capsys):
    (tmp_path / "file").write_text("")
    assert cli.main([str(PRETRAINED), "--out", str(tmp_path / "file" / "p.onnx")]) == 2
    assert "--out" in _one_line(capsys)


def test_the_checker_imports_neither_jax_nor_jaxmotion():
    """The checker is run by path: importing jaxmotion would import MJX, hence JAX."""
    src = (REPO / "jaxmotion" / "export" / "check_policy.py").read_text().splitlines()
    imports = [line.split()[1] for line in src if line.startswith(("import ", "from "))]
    assert not [m for m in imports if m.split(".")[0] in ("jax", "jaxmotion", "flax")], imports
