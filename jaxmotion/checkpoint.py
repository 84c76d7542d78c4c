"""Run folders: config JSON plus orbax checkpoints of the whole TrainState.

A run folder ``runs/<experiment>/<timestamp>/`` holds ``config.json`` (the experiment name and the
full typed config, enough to rebuild everything), ``checkpoints/<iteration>/`` written by orbax
(atomically: a temporary directory renamed on completion, so a killed run never leaves a
half-written checkpoint that looks valid), ``metrics.jsonl`` and TensorBoard events.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import jax
import orbax.checkpoint as ocp

from jaxmotion import config as C

CONFIG_FILE = "config.json"


def write_config(run_dir: Path, experiment: str, cfg: Any, resolved: dict | None = None) -> None:
    """Writes ``config.json``; ``resolved`` records what the config left to the machine (e.g. the
    physics backend that ``auto`` chose), for the reader, not for rebuilding."""
    run_dir.mkdir(parents=True, exist_ok=True)
    tmp = run_dir / (CONFIG_FILE + ".tmp")
    doc = {"experiment": experiment, "config": C.to_dict(cfg)}
    if resolved:
        doc["resolved"] = resolved
    tmp.write_text(json.dumps(doc, indent=2))
    tmp.replace(run_dir / CONFIG_FILE)


def read_config(run_dir: Path, cls: type) -> tuple[str, Any]:
    """(experiment name, config) of a run folder; a clear error if it is not one."""
    path = Path(run_dir) / CONFIG_FILE
    if not path.exists():
        raise FileNotFoundError(f"{run_dir} is not a run folder: no {CONFIG_FILE}")
    d = json.loads(path.read_text())
    return d["experiment"], C.from_dict(cls, d["config"])


def manager(run_dir: Path, max_to_keep: int = 3) -> ocp.CheckpointManager:
    opts = ocp.CheckpointManagerOptions(max_to_keep=max_to_keep, create=True)
    return ocp.CheckpointManager(Path(run_dir).absolute() / "checkpoints", options=opts)


def _flat(state: Any) -> dict[str, Any]:
    """Non-empty leaves keyed by their tree path (orbax refuses zero-size arrays, and MJX data
    has some, e.g. ``act`` of a model without actuator activations)."""
    leaves = jax.tree_util.tree_flatten_with_path(state)[0]
    return {jax.tree_util.keystr(p): x for p, x in leaves if x.size}


def save(mgr: ocp.CheckpointManager, step: int, state: Any) -> None:
    """Writes ``state`` as checkpoint ``step`` and waits until it is committed on disk."""
    mgr.save(step, args=ocp.args.StandardSave(_flat(state)))
    mgr.wait_until_finished()


def restore(mgr: ocp.CheckpointManager, like: Any, step: int | None = None) -> tuple[Any, int]:
    """Restores the latest (or given) checkpoint into the structure and shardings of ``like``."""
    step = mgr.latest_step() if step is None else step
    if step is None:
        raise FileNotFoundError(f"no checkpoint in {mgr.directory}")
    abstract = jax.tree.map(ocp.utils.to_shape_dtype_struct, _flat(like))
    flat = mgr.restore(step, args=ocp.args.StandardRestore(abstract))
    paths, treedef = jax.tree_util.tree_flatten_with_path(like)
    leaves = [flat.get(jax.tree_util.keystr(p), x) for p, x in paths]
    return jax.tree_util.tree_unflatten(treedef, leaves), step
