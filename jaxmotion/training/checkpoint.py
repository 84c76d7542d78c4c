"""Run folders: config JSON plus orbax checkpoints of the whole TrainState.

A run folder ``runs/<experiment>/<timestamp>/`` holds ``config.json`` (the experiment name and the
full typed config, enough to rebuild everything), ``checkpoints/<iteration>/`` written by orbax
(atomically: a temporary directory renamed on completion, so a killed run never leaves a
half-written checkpoint that looks valid), ``metrics.jsonl`` and TensorBoard events.

``python -m jaxmotion.training.runs slim <run-folder> <out-folder>`` writes a copy of a run whose
latest checkpoint leaves out the per-environment state (``env_state``, ``obs``): at 4096 MJX
environments that state is ~40 kB per environment, most of the checkpoint. The copy evaluates and
resumes like the run (its ``SLIM_FILE`` lists what is missing; ``restore`` keeps the freshly reset
environments of its template there), so a run trained on a GPU can be carried to a laptop.
"""

from __future__ import annotations

import json
import shutil
from pathlib import Path
from typing import Any

import jax
import orbax.checkpoint as ocp

from jaxmotion import config as C

CONFIG_FILE = "config.json"
SLIM_FILE = "slim.json"
PER_ENV = ("env_state", "obs")
"""The ``TrainState`` fields holding per-environment leaves, which a slim checkpoint leaves out."""


def field_of(key: str) -> str:
    """The top-level field a leaf's key path names: ``.obs_norm.mean`` -> ``obs_norm``,
    ``['a']`` -> ``a``. Matching whole fields, not key prefixes: ``.obs`` is no prefix match for
    ``.obs_norm`` (slim copies written before 2026-12-07 lost the observation statistics so)."""
    head = key.lstrip(".").split(".", 1)[0]
    if head.startswith("['"):
        return head[2:].split("']", 1)[0]
    return head.split("[", 1)[0]


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


def restore(
    mgr: ocp.CheckpointManager, like: Any, step: int | None = None, skip: tuple[str, ...] = ()
) -> tuple[Any, int]:
    """Restores the latest (or given) checkpoint into the structure and shardings of ``like``;
    leaves of the fields in ``skip`` (and those a slim checkpoint left out) keep ``like``'s values."""
    step = mgr.latest_step() if step is None else step
    if step is None:
        raise FileNotFoundError(f"no checkpoint in {mgr.directory}")
    slim = Path(mgr.directory) / str(step) / SLIM_FILE
    left_out = tuple(f.lstrip(".") for f in json.loads(slim.read_text())["left_out"]) if slim.exists() else ()
    abstract = {
        k: ocp.utils.to_shape_dtype_struct(x)
        for k, x in _flat(like).items()
        if field_of(k) not in tuple(skip) + left_out
    }
    # Leaves skipped on purpose are on disk but not asked for: a partial restore,
    # which must still find every leaf it asks for.
    if skip:
        args = ocp.args.PyTreeRestore(
            item=abstract, restore_args=ocp.checkpoint_utils.construct_restore_args(abstract), partial_restore=True
        )
    else:
        args = ocp.args.StandardRestore(abstract)
    flat = mgr.restore(step, args=args)
    missing = sorted(k for k in abstract if not isinstance(flat.get(k), jax.Array))
    if missing:
        raise ValueError(f"checkpoint {step} in {mgr.directory} has no {', '.join(missing[:5])}")
    paths, treedef = jax.tree_util.tree_flatten_with_path(like)
    leaves = [flat.get(jax.tree_util.keystr(p), x) for p, x in paths]
    return jax.tree_util.tree_unflatten(treedef, leaves), step


def slim(run_dir: Path, out_dir: Path, like: Any) -> int:
    """Copies run ``run_dir`` to ``out_dir`` (config, metrics, plots) with its latest checkpoint
    restored into ``like`` and written again without the ``PER_ENV`` leaves; returns the step."""
    run_dir, out_dir = Path(run_dir), Path(out_dir)
    mgr = manager(run_dir)
    state, step = restore(mgr, like)
    mgr.close()
    out_dir.mkdir(parents=True, exist_ok=False)
    for f in run_dir.iterdir():
        if f.is_file():
            shutil.copy2(f, out_dir / f.name)
    out = manager(out_dir)
    kept = {k: x for k, x in _flat(state).items() if field_of(k) not in PER_ENV}
    out.save(step, args=ocp.args.StandardSave(kept))
    out.wait_until_finished()
    out.close()
    (out_dir / "checkpoints" / str(step) / SLIM_FILE).write_text(json.dumps({"left_out": list(PER_ENV)}))
    return step
