"""Runs an exported jaxmotion policy in plain MuJoCo with onnxruntime: no JAX, no jaxmotion.

    python check_policy.py POLICY.onnx EPISODE.npz OUT.npz

Run it by path (``python path/to/check_policy.py``): it imports numpy, mujoco and onnxruntime
only, and doubles as the example of driving an exported policy. ``POLICY.json`` beside the model
(the sidecar ``python -m jaxmotion.export`` writes) names the scene's MJCF, the rates and the
input layout. ``EPISODE.npz`` holds the start window (``qpos`` [F, nq], ``qvel`` [F, nv], oldest
first), the tracker's reference inputs per step (``ref_qpos`` [T, nq], ``ref_qvel`` [T, nv];
[T, 0] for other policies) and, optionally, states the policy is also evaluated on open loop
(``state_qpos`` [T, F, nq], ``state_qvel`` [T, F, nv]). ``OUT.npz`` gets, per control step, the
PD targets (``targets`` [T, n_dof]), the root height after the step (``root_height`` [T]), the
open-loop targets (``open_loop`` [T, n_dof]) and ``jax_imported`` (whether anything imported JAX).

One control step: the policy maps the last F states to PD targets, written as the actuators'
controls and held for ``substeps`` physics steps of one ``MjData`` kept across steps.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import mujoco
import numpy as np
import onnxruntime as ort


def load(policy: Path) -> tuple[ort.InferenceSession, dict, mujoco.MjModel]:
    """(session, sidecar, model) of an exported policy."""
    meta = json.loads(policy.with_suffix(".json").read_text())
    model = mujoco.MjModel.from_xml_path(str(policy.parent / meta["files"]["scene"]))
    opts = ort.SessionOptions()
    opts.intra_op_num_threads = opts.inter_op_num_threads = 1
    return ort.InferenceSession(str(policy), opts, providers=["CPUExecutionProvider"]), meta, model


def act(session: ort.InferenceSession, qpos: np.ndarray, qvel: np.ndarray, ref=None) -> np.ndarray:
    """PD targets [n_dof] of the window ``qpos`` [F, nq], ``qvel`` [F, nv] (and the tracker's
    reference (ref_qpos [nq], ref_qvel [nv]))."""
    feed = {"qpos": qpos.astype(np.float32), "qvel": qvel.astype(np.float32)}
    if ref is not None:
        feed.update(ref_qpos=ref[0].astype(np.float32), ref_qvel=ref[1].astype(np.float32))
    return session.run(["pd_target"], feed)[0]


def rollout(session, meta: dict, model: mujoco.MjModel, episode: dict) -> dict:
    """The closed-loop episode in MuJoCo from the episode's start window."""
    data = mujoco.MjData(model)
    nq, nv, substeps = meta["nq"], meta["nv"], meta["substeps"]
    qpos, qvel = episode["qpos"].astype(np.float64), episode["qvel"].astype(np.float64)
    data.qpos[:nq], data.qvel[:nv] = qpos[-1], qvel[-1]
    tracking = episode["ref_qpos"].shape[-1] > 0
    targets, heights = [], []
    for t in range(len(episode["ref_qpos"])):
        ref = (episode["ref_qpos"][t], episode["ref_qvel"][t]) if tracking else None
        target = act(session, qpos, qvel, ref)
        data.ctrl[:] = target
        for _ in range(substeps):
            mujoco.mj_step(model, data)
        qpos = np.concatenate([qpos[1:], data.qpos[None, :nq]])
        qvel = np.concatenate([qvel[1:], data.qvel[None, :nv]])
        targets.append(target)
        heights.append(data.qpos[2])
    return {"targets": np.asarray(targets, np.float32), "root_height": np.asarray(heights)}


def open_loop(session, episode: dict) -> np.ndarray:
    """The policy's PD targets on the episode's recorded windows ([T, n_dof]; [0] if none)."""
    if "state_qpos" not in episode:
        return np.zeros((0,), np.float32)
    tracking = episode["ref_qpos"].shape[-1] > 0
    out = []
    for t in range(len(episode["state_qpos"])):
        ref = (episode["ref_qpos"][t], episode["ref_qvel"][t]) if tracking else None
        out.append(act(session, episode["state_qpos"][t], episode["state_qvel"][t], ref))
    return np.asarray(out, np.float32)


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("policy", type=Path, help="the exported .onnx (its .json sidecar beside it)")
    p.add_argument("episode", type=Path, help=".npz with the start window and reference inputs")
    p.add_argument("out", type=Path, help=".npz to write the episode's targets and root heights to")
    args = p.parse_args(argv)
    session, meta, model = load(args.policy)
    episode = dict(np.load(args.episode))
    out = rollout(session, meta, model, episode)
    out["open_loop"] = open_loop(session, episode)
    out["jax_imported"] = np.asarray("jax" in sys.modules)
    np.savez(args.out, **out)
    return 0


if __name__ == "__main__":
    sys.exit(main())
