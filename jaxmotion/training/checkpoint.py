"""Run folders: config JSON plus orbax checkpoints of the whole TrainState.

A run folder ``runs/<experiment>/<timestamp>/`` holds ``config.json`` (the experiment name and the
full typed config, enough to rebuild everything, plus ``resolved``: what the config left to the
machine, e.g. the physics backend and the absolute data folder, for the reader),
``checkpoints/<iteration>/`` written by orbax (atomically: a temporary directory renamed on
completion, so a killed run never leaves a half-written checkpoint that looks valid),
``metrics.jsonl`` and TensorBoard events.

A checkpoint can still be damaged afterwards (a disk filled up, a file cut short by a copy):
``restore`` then falls back to the newest older checkpoint that restores, saying which ones it
skipped, and a run folder that cannot be used at all (no ``config.json``, one that is not a
config, no intact checkpoint) is a ``RunFolderError``: one line on the command line.

``python -m jaxmotion.training.runs slim <run-folder> <out-folder>`` writes a copy of a run whose
latest checkpoint leaves out the per-environment state (``env_state``, ``obs``): at 4096 MJX
environments that state is ~40 kB per environment, most of the checkpoint. The copy evaluates and
resumes like the run (its ``SLIM_FILE`` lists what is missing; ``restore`` keeps the freshly reset
environments of its template there), so a run trained on a GPU can be carried to a laptop.
"""

from __future__ import annotations

import contextlib
import gc
import json
import re
import shutil
import sys
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any

import jax
import orbax.checkpoint as ocp

from jaxmotion import config as C
from jaxmotion.config.errors import JaxmotionError

CONFIG_FILE = "config.json"
SLIM_FILE = "slim.json"
DAMAGED_DIR = "damaged"
"""Where a resumed run sets aside the damaged checkpoints it skipped (``set_aside``)."""
PER_ENV = ("env_state", "obs", "policy_carry")
"""The ``TrainState`` fields holding per-environment leaves, which a slim checkpoint leaves out."""


class RunFolderError(JaxmotionError):
    """A run folder that cannot be used: missing, no ``config.json``, a ``config.json`` that is
    not a config, or no checkpoint that restores."""


class CheckpointDamaged(Exception):
    """Internal: one checkpoint cannot be read (a file cut short or missing); ``restore`` falls
    back to an older one."""

    def __init__(self, step: int, why: str):
        super().__init__(f"checkpoint {step} is damaged ({why})")
        self.step, self.why = step, why


def field_of(key: str) -> str:
    """The top-level field a leaf's key path names: ``.obs_norm.mean`` -> ``obs_norm``,
    ``['a']`` -> ``a``. Matching whole fields, not key prefixes: ``.obs`` is no prefix match for
    ``.obs_norm`` (slim copies written before 2026-12-07 lost the observation statistics so)."""
    head = key.lstrip(".").split(".", 1)[0]
    if head.startswith("['"):
        return head[2:].split("']", 1)[0]
    return head.split("[", 1)[0]


# --------------------------------------------------------------------------- config.json


def write_config(run_dir: Path, experiment: str, cfg: Any, resolved: dict | None = None) -> None:
    """Writes ``config.json``; ``resolved`` records what the config left to the machine (e.g. the
    physics backend that ``auto`` chose, the data folder), for the reader, not for rebuilding."""
    run_dir.mkdir(parents=True, exist_ok=True)
    tmp = run_dir / (CONFIG_FILE + ".tmp")
    doc = {"experiment": experiment, "config": C.to_dict(cfg)}
    if resolved:
        doc["resolved"] = resolved
    tmp.write_text(json.dumps(doc, indent=2))
    tmp.replace(run_dir / CONFIG_FILE)


def read_doc(run_dir: Path) -> dict:
    """``config.json`` of a run folder as a dict with a string ``experiment`` and a mapping
    ``config``; a ``RunFolderError`` saying what is wrong otherwise."""
    run_dir = Path(run_dir)
    path = run_dir / CONFIG_FILE
    if not run_dir.exists():
        raise RunFolderError(f"{run_dir}: no such run folder")
    if not run_dir.is_dir():
        raise RunFolderError(f"{run_dir} is not a run folder (it is a file)")
    if not path.is_file():
        raise RunFolderError(f"{run_dir} is not a run folder: no {CONFIG_FILE}")
    try:
        doc = json.loads(path.read_bytes())
    except OSError as e:
        raise RunFolderError(f"{path}: cannot read it ({e.strerror})") from None
    except ValueError as e:  # JSONDecodeError, or bytes that are no text
        raise RunFolderError(f"{path} is damaged: not JSON ({str(e).splitlines()[0][:120]})") from None
    if not isinstance(doc, dict):
        raise RunFolderError(f"{path} is damaged: not a JSON object")
    for key, kind, name in (("experiment", str, "a string"), ("config", dict, "an object")):
        if key not in doc:
            raise RunFolderError(f'{path} is damaged: no "{key}"')
        if not isinstance(doc[key], kind):
            raise RunFolderError(f'{path} is damaged: "{key}" is not {name}')
    return doc


def read_config(run_dir: Path, cls: type) -> tuple[str, Any]:
    """(experiment name, config) of a run folder; a ``RunFolderError`` if it is not one (no
    folder, no ``config.json``, not JSON, no experiment or config, fields of the wrong type)."""
    doc = read_doc(run_dir)
    try:
        cfg = C.from_dict(cls, doc["config"])
    except C.ConfigError as e:
        raise RunFolderError(f"{Path(run_dir) / CONFIG_FILE} holds no config this version can rebuild: {e}") from None
    return doc["experiment"], cfg


def read_resolved(run_dir: Path) -> dict:
    """The ``resolved`` section of a run's ``config.json`` (``{}`` if it has none or it is not a
    mapping); call after ``read_config`` has checked the file."""
    try:
        resolved = read_doc(run_dir).get("resolved")
    except RunFolderError:
        return {}
    return resolved if isinstance(resolved, dict) else {}


# --------------------------------------------------------------------------- checkpoints


def manager(run_dir: Path, max_to_keep: int = 3) -> ocp.CheckpointManager:
    opts = ocp.CheckpointManagerOptions(max_to_keep=max_to_keep, create=True)
    return ocp.CheckpointManager(Path(run_dir).absolute() / "checkpoints", options=opts)


def has_checkpoint(run_dir: Path) -> bool:
    """Whether ``run_dir/checkpoints`` holds a committed checkpoint (a folder named by a step)."""
    d = Path(run_dir) / "checkpoints"
    return d.is_dir() and any(p.is_dir() and p.name.isdigit() for p in d.iterdir())


def _flat(state: Any) -> dict[str, Any]:
    """Non-empty leaves keyed by their tree path (orbax refuses zero-size arrays, and MJX data
    has some, e.g. ``act`` of a model without actuator activations)."""
    leaves = jax.tree_util.tree_flatten_with_path(state)[0]
    return {jax.tree_util.keystr(p): x for p, x in leaves if x.size}


def save(mgr: ocp.CheckpointManager, step: int, state: Any) -> None:
    """Writes ``state`` as checkpoint ``step`` and waits until it is committed on disk."""
    mgr.save(step, args=ocp.args.StandardSave(_flat(state)))
    mgr.wait_until_finished()


def _why(e: BaseException, step_dir: Path) -> str:
    """A short reason for a failed read: tensorstore's status and the file it names
    (``data loss: default/manifest.ocdbt``), else the error's type and first line."""
    msg = str(e).splitlines()[0] if str(e) else ""
    msg = msg.split(" See full TensorStore details")[0].rstrip(". ")
    code = re.match(r"([A-Z][A-Z_]{3,}): ", msg)
    files = re.findall(r'local file "([^"]+)"', msg)
    if code and files:
        name = files[-1]
        prefix = str(step_dir.absolute()) + "/"
        name = name[len(prefix) :] if name.startswith(prefix) else name
        return f"{code.group(1).lower().replace('_', ' ')}: {name or '.'}"
    if len(msg) > 120:  # at a word, not mid-word
        msg = msg[:120].rsplit(" ", 1)[0] + " ..."
    return f"{type(e).__name__}: {msg}"


def _mismatch(step_dir: Path, abstract: dict, partial: bool) -> str | None:
    """Why checkpoint ``step_dir``'s recorded structure does not fit ``abstract`` (a leaf it
    lacks or has in another shape; with ``partial`` False, also leaves it has beyond them), or
    None when it fits or its metadata cannot be read (then the checkpoint is damaged)."""
    try:
        tree = ocp.StandardCheckpointHandler().metadata(step_dir / "default").tree
        shapes = {k: tuple(getattr(v, "shape", ())) for k, v in tree.items()}
    except Exception:  # noqa: BLE001 - unreadable metadata: damage, not a mismatch
        return None
    lacks = sorted(k for k in abstract if k not in shapes)
    if lacks:
        return f"has no {', '.join(lacks[:5])}"
    other = sorted(k for k, x in abstract.items() if shapes[k] != tuple(x.shape))
    if other:
        return "holds " + ", ".join(f"{k} of shape {shapes[k]} (not {tuple(abstract[k].shape)})" for k in other[:3])
    extra = sorted(set(shapes) - set(abstract))
    if extra and not partial:
        return f"holds leaves this state does not have: {', '.join(extra[:5])}"
    return None


def _from_readers(u) -> bool:
    """Whether an unraisable exception (``sys.unraisablehook``'s argument) was raised in orbax's
    asynchronous readers, asyncio or tensorstore."""
    files = [f.filename for f in traceback.extract_tb(u.exc_traceback)] if u.exc_traceback else []
    return any(("orbax" in f or "asyncio" in f or "tensorstore" in f) for f in files)


class _DropClosedLoopCallbacks:
    """An unraisable hook that drops ``RuntimeError('Event loop is closed')`` from asyncio and
    hands everything else to the hook it wraps. After a failed read, tensorstore still completes
    the other arrays' reads on its own threads and their callbacks find orbax's event loop closed,
    at any later time."""

    def __init__(self, hook):
        self.hook = hook

    def __call__(self, u) -> None:
        if not (isinstance(u.exc_value, RuntimeError) and "Event loop is closed" in str(u.exc_value)):
            self.hook(u)


@contextlib.contextmanager
def _quiet_failed_reads():
    """Keeps a failed read to the one line this module makes of it: drops what orbax's readers
    report through ``sys.unraisablehook`` meanwhile (coroutines of the other arrays never
    awaited), and, once a read failed, the closed-loop callbacks that come later."""
    hook = sys.unraisablehook
    sys.unraisablehook = lambda u: None if _from_readers(u) else hook(u)
    failed = False
    try:
        yield
    except BaseException:
        failed = True
        raise
    finally:
        gc.collect()  # coroutines left behind report now, while the hook is ours
        late = failed and not isinstance(hook, _DropClosedLoopCallbacks)
        sys.unraisablehook = _DropClosedLoopCallbacks(hook) if late else hook


def _restore_step(mgr: ocp.CheckpointManager, like: Any, step: int, skip: tuple[str, ...]) -> Any:
    """Checkpoint ``step`` restored into ``like`` (see ``restore``). Raises ``ValueError`` when
    it does not fit ``like``'s structure, ``CheckpointDamaged`` when it cannot be read."""
    step_dir = Path(mgr.directory) / str(step)
    try:
        slim = step_dir / SLIM_FILE
        left_out = tuple(f.lstrip(".") for f in json.loads(slim.read_text())["left_out"]) if slim.exists() else ()
    except (OSError, ValueError, KeyError, TypeError, AttributeError) as e:
        raise CheckpointDamaged(step, f"{SLIM_FILE}: {type(e).__name__}") from None
    abstract = {
        k: ocp.utils.to_shape_dtype_struct(x) for k, x in _flat(like).items() if field_of(k) not in skip + left_out
    }
    # Leaves skipped on purpose are on disk but not asked for: a partial restore,
    # which must still find every leaf it asks for.
    if skip:
        args = ocp.args.PyTreeRestore(
            item=abstract, restore_args=ocp.checkpoint_utils.construct_restore_args(abstract), partial_restore=True
        )
    else:
        args = ocp.args.StandardRestore(abstract)
    try:
        with _quiet_failed_reads():
            flat = mgr.restore(step, args=args)
    except Exception as e:  # noqa: BLE001 - tensorstore and orbax raise many kinds
        problem = _mismatch(step_dir, abstract, partial=bool(skip))
        if problem is not None:
            raise ValueError(f"checkpoint {step} in {mgr.directory} {problem}") from e
        raise CheckpointDamaged(step, _why(e, step_dir)) from e
    missing = sorted(k for k in abstract if not isinstance(flat.get(k), jax.Array))
    if missing:
        raise ValueError(f"checkpoint {step} in {mgr.directory} has no {', '.join(missing[:5])}")
    paths, treedef = jax.tree_util.tree_flatten_with_path(like)
    leaves = [flat.get(jax.tree_util.keystr(p), x) for p, x in paths]
    return jax.tree_util.tree_unflatten(treedef, leaves)


def _stderr(line: str) -> None:
    print(line, file=sys.stderr)


def restore_newest(
    mgr: ocp.CheckpointManager,
    like: Any,
    skip: tuple[str, ...] = (),
    say: Callable[[str], None] = _stderr,
    doing: str = "loading",
) -> tuple[Any, int, list[int]]:
    """(state, step, damaged steps): the newest checkpoint that restores into ``like``, trying
    older ones past damaged ones, with one line through ``say`` per checkpoint skipped
    ("checkpoint 20 is damaged (...); loading 10"; ``doing`` names what the caller does).

    Raises ``RunFolderError`` when there is no checkpoint or none restores, and ``ValueError``
    (no fallback: older checkpoints have the same structure) when one does not fit ``like``.
    """
    steps = sorted(mgr.all_steps(), reverse=True)
    if not steps:
        raise RunFolderError(f"no checkpoint in {mgr.directory}")
    damaged: list[CheckpointDamaged] = []
    for step in steps:
        try:
            state = _restore_step(mgr, like, step, tuple(skip))
        except CheckpointDamaged as e:
            damaged.append(e)
            continue
        for d in damaged:
            say(f"{d}; {doing} {step}")
        return state, step, [d.step for d in damaged]
    raise RunFolderError(
        f"no checkpoint in {mgr.directory} can be read: " + "; ".join(f"{d.step}: {d.why}" for d in damaged)
    )


def restore(
    mgr: ocp.CheckpointManager, like: Any, step: int | None = None, skip: tuple[str, ...] = ()
) -> tuple[Any, int]:
    """Restores the given checkpoint (default: the newest that can be read, see
    ``restore_newest``) into the structure and shardings of ``like``; leaves of the fields in
    ``skip`` (and those a slim checkpoint left out) keep ``like``'s values."""
    if step is None:
        state, step, _ = restore_newest(mgr, like, skip)
        return state, step
    try:
        return _restore_step(mgr, like, step, tuple(skip)), step
    except CheckpointDamaged as e:
        raise RunFolderError(f"{e} in {mgr.directory}") from None


def restore_run(
    run_dir: Path, like: Any, skip: tuple[str, ...] = (), say: Callable[[str], None] = _stderr, doing: str = "loading"
) -> tuple[Any, int]:
    """``restore_newest`` of the run folder ``run_dir`` (without creating its checkpoint folder)."""
    if not has_checkpoint(run_dir):
        raise RunFolderError(f"no checkpoint in {Path(run_dir) / 'checkpoints'}")
    mgr = manager(run_dir)
    try:
        state, step, _ = restore_newest(mgr, like, skip, say, doing)
    finally:
        mgr.close()
    return state, step


def set_aside(run_dir: Path, steps: list[int]) -> list[Path]:
    """Moves the damaged checkpoints ``steps`` of ``run_dir`` into ``run_dir/damaged/`` (so a
    resumed run can write those steps again; kept for inspection) and returns where they went.
    Close the run's checkpoint manager first and open a new one after."""
    out = []
    for step in steps:
        dest = Path(run_dir) / DAMAGED_DIR / str(step)
        n = 1
        while dest.exists():
            dest = Path(run_dir) / DAMAGED_DIR / f"{step}-{n}"
            n += 1
        dest.parent.mkdir(parents=True, exist_ok=True)
        shutil.move(str(Path(run_dir) / "checkpoints" / str(step)), dest)
        out.append(dest)
    return out


def slim(run_dir: Path, out_dir: Path, like: Any) -> int:
    """Copies run ``run_dir`` to ``out_dir`` (config, metrics, plots) with its latest checkpoint
    restored into ``like`` and written again without the ``PER_ENV`` leaves; returns the step."""
    run_dir, out_dir = Path(run_dir), Path(out_dir)
    state, step = restore_run(run_dir, like)
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
