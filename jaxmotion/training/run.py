"""The training driver: Python between compiled chunks (``loop.make_train_chunk``).

It shows a progress bar, appends ``metrics.jsonl``, writes TensorBoard events and orbax
checkpoints between chunks, and runs the hooks a run asks for (periodic evaluation, hard-negative
mining) without knowing what they do. ``resume=<run-folder>`` continues a killed run from its latest
checkpoint that can be read (older ones past damaged ones); on CPU the result is identical to an
uninterrupted run (same chunking, the RNG lives in the checkpointed state).

After every chunk the driver checks the chunk's logged metrics and the state's parameters and
statistics: a run that went non-finite stops with ``TrainingDiverged`` before that chunk's
checkpoint, so its last checkpoint is a good one. A new run that fails before its first
checkpoint removes the folder it created.
"""

from __future__ import annotations

import dataclasses
import functools
import json
import math
import shutil
import sys
import time
from pathlib import Path
from collections.abc import Callable, Sequence

import jax
import jax.numpy as jnp
import numpy as np

from jaxmotion.config.errors import ConfigError, JaxmotionError
from jaxmotion.motion.data import data_dir
from jaxmotion.physics import backends
from jaxmotion.training import checkpoint as ckpt
from jaxmotion.training.learner import TrainConfig, TrainState
from jaxmotion.training.loop import make_mesh, make_train_chunk, shard_state
from jaxmotion.training.runs import (
    check_init_from,
    init_from,
    make_learner,
    new_run_dir,
    transfer_decoder,
    use_recorded_data,
)

CHECKED_FIELDS = (
    "policy_params",
    "critic_params",
    "disc_params",
    "opt_state",
    "disc_opt_state",
    "obs_norm",
    "disc_norm",
    "popart",
)
"""The ``TrainState`` fields checked for non-finite values after every chunk: what the learner
updates (networks, optimisers, statistics). Environment states are the physics' business."""


class TrainingDiverged(JaxmotionError):
    """The losses, statistics or parameters of a run went non-finite (NaN or inf)."""


@dataclasses.dataclass(frozen=True)
class ChunkEnd:
    """Where a run stands after a chunk, as hooks see it."""

    run_dir: Path
    iteration: int
    chunks: int
    """Chunks this process has run."""
    done: bool
    """The run's last chunk."""
    last: dict
    """The last logged row (iteration, samples, metrics)."""
    log: Callable[[dict], None]
    """Appends a row of extra metrics for this iteration (``metrics.jsonl``, TensorBoard)."""
    say: Callable[[str], None]
    """Prints a line above the progress bar."""


@dataclasses.dataclass(frozen=True)
class Hook:
    """Work between compiled chunks: ``run(learner, ts, end)`` when ``due(cfg, end)``.

    A hook with ``before_checkpoint`` may return a changed state (it is checkpointed with the
    chunk, so a resumed run sees it); the others run after the checkpoint and return nothing."""

    run: Callable[..., TrainState | None]
    due: Callable[[TrainConfig, ChunkEnd], bool]
    before_checkpoint: bool = False


def _log_row(path: Path, writer, last: dict, row: dict) -> None:
    row = {"iteration": last["iteration"], "samples": last["samples"], **row}
    with open(path, "a") as f:
        f.write(json.dumps(row) + "\n")
    if writer is not None:
        for k, v in row.items():
            if k not in ("iteration", "samples"):
                writer.add_scalar(k, v, row["iteration"])
    last.update(row)


@dataclasses.dataclass
class RunResult:
    run_dir: Path
    state: TrainState
    metrics: list[dict]


def _scalars(metrics: dict, i: int) -> dict:
    """The i-th iteration's metrics as JSON-able floats (vectors are split per element)."""
    out = {}
    for k, v in metrics.items():
        x = np.asarray(v[i])
        if x.ndim == 0:
            out[k] = float(x)
        else:
            for j, e in enumerate(x.reshape(-1)):
                out[f"{k}/{j}"] = float(e)
    return out


def _row_iteration(line: str) -> int | None:
    """The iteration of a ``metrics.jsonl`` line, or None if the line is no row (blank, cut
    short by a kill mid-write, not an object with an integer ``iteration``)."""
    try:
        row = json.loads(line)
    except ValueError:
        return None
    it = row.get("iteration") if isinstance(row, dict) else None
    return it if isinstance(it, int) and not isinstance(it, bool) else None


def _trim_metrics(path: Path, upto: int) -> None:
    """Keeps the log rows of iterations up to ``upto`` (the state a resume starts from: rows
    written after its checkpoint, or before any, would repeat) and drops lines that are no row."""
    if not path.exists():
        return
    keep = []
    for line in path.read_text().splitlines():
        it = _row_iteration(line)
        if it is not None and it <= upto:
            keep.append(line)
    tmp = path.with_suffix(".tmp")
    tmp.write_text("".join(line + "\n" for line in keep))
    tmp.replace(path)


def nonfinite_metrics(rows: Sequence[dict]) -> tuple[int, list[str]] | None:
    """(iteration, ``"key = value"`` of its non-finite metrics) of the first row holding one, or
    None when every value is finite."""
    for row in rows:
        bad = [f"{k} = {v}" for k, v in row.items() if isinstance(v, float) and not math.isfinite(v)]
        if bad:
            return row["iteration"], bad
    return None


@jax.jit
def _all_finite(fields: dict) -> dict:
    """Per field of ``fields``: whether every floating-point leaf is finite (one compiled call)."""
    return {
        f: jnp.stack(
            [jnp.isfinite(x).all() for x in jax.tree.leaves(v) if jnp.issubdtype(x.dtype, jnp.inexact)]
            + [jnp.asarray(True)]
        ).all()
        for f, v in fields.items()
    }


def nonfinite_fields(ts: TrainState) -> list[str]:
    """The ``CHECKED_FIELDS`` of ``ts`` holding a non-finite value (one compiled call, one
    device transfer)."""
    flags = jax.device_get(_all_finite({f: getattr(ts, f) for f in CHECKED_FIELDS}))
    return [f for f, ok in flags.items() if not bool(ok)]


def divergence(
    run_dir: Path, rows: Sequence[dict], ts: TrainState, last_good: int | None, fresh: bool = False
) -> str | None:
    """The message of a chunk that went non-finite (its logged ``rows``, the state after it), or
    None; ``last_good``: the run's newest checkpoint (None: none written, and a ``fresh`` run's
    folder is removed)."""
    found = nonfinite_metrics(rows)
    fields = nonfinite_fields(ts)
    if found is None and not fields:
        return None
    if found is not None:
        it, bad = found
        what = ", ".join(bad[:3]) + (f", and {len(bad) - 3} more" if len(bad) > 3 else "")
    else:
        it, what = int(ts.iteration), "non-finite " + ", ".join(fields)
    if last_good is None:
        kept = "no checkpoint was written" + (f", so {run_dir} is removed" if fresh else "")
    else:
        kept = f"the last good checkpoint is {last_good} in {run_dir / 'checkpoints'}"
    return f"training went non-finite at iteration {it} ({what}); {kept}; lower the learning rates or check the clips"


def _resumed(cfg: TrainConfig) -> TrainConfig:
    """The config a resumed run continues with: its saved one, with this ``cfg``'s length and
    checkpoint interval (the only settings a resume may change) and ``resume``."""
    _, saved = ckpt.read_config(Path(cfg.resume), TrainConfig)
    return dataclasses.replace(
        saved, iterations=cfg.iterations, resume=cfg.resume, checkpoint_every=cfg.checkpoint_every
    )


def _check_sizes(cfg: TrainConfig, devices: int) -> None:
    """Settings the driver needs, checked before a run folder exists."""
    if cfg.iterations % cfg.chunk:
        raise ConfigError(f"iterations ({cfg.iterations}) must be a multiple of chunk ({cfg.chunk})")
    for key, value in (
        ("ppo.num_envs", cfg.ppo.num_envs),
        ("ppo.minibatch_size", cfg.ppo.minibatch_size),
        ("disc.minibatch_size", cfg.disc.minibatch_size),
    ):
        if value % devices:  # each device takes an equal share of the batch and of every minibatch
            raise ConfigError(f"{key} ({value}) must be divisible by the device count ({devices})")


def _record_config(run_dir: Path, experiment: str, cfg: TrainConfig, resolved: dict) -> None:
    """Writes a new run's ``config.json``, or a resumed run's when its length or checkpoint
    interval changed (so a later plain ``resume=`` keeps them), keeping what it resolved."""
    if not cfg.resume:
        ckpt.write_config(run_dir, experiment, cfg, resolved=resolved)
        return
    saved_experiment, saved = ckpt.read_config(run_dir, TrainConfig)
    now = dataclasses.replace(cfg, resume="")
    if now != saved:
        ckpt.write_config(run_dir, saved_experiment, now, resolved=ckpt.read_resolved(run_dir))


PHYSICS_LOG = "physics.log"
"""MuJoCo's warnings of a run, counted per chunk (``backends.WARNINGS``), in its run folder."""


def log_physics_warnings(run_dir: Path, iteration: int) -> int:
    """Appends the MuJoCo warnings counted since the last call to ``run_dir/physics.log`` (one
    line per message: iteration, count, message) and returns their total (0: nothing written)."""
    counts = backends.WARNINGS.take()
    if counts:
        with open(run_dir / PHYSICS_LOG, "a") as f:
            for msg, n in sorted(counts.items()):
                f.write(f"iteration {iteration}: {n} x {msg}\n")
    return sum(counts.values())


def _remove_unfinished(run_dir: Path) -> None:
    """Removes a new run's folder that holds no checkpoint (it failed before the first)."""
    if run_dir.is_dir() and not ckpt.has_checkpoint(run_dir):
        shutil.rmtree(run_dir, ignore_errors=True)


def train(
    experiment: str,
    cfg: TrainConfig,
    run_dir: Path | None = None,
    progress: bool = True,
    tensorboard: bool = True,
    stop_after_chunks: int | None = None,
    on_chunk: Callable[[int, dict], None] | None = None,
    hooks: Sequence[Hook] = (),
    until: Callable[[ChunkEnd], bool] | None = None,
) -> RunResult:
    """Trains ``cfg`` into ``run_dir`` (resuming when ``cfg.resume`` names a run folder: its saved
    settings, with ``cfg``'s ``iterations`` and ``checkpoint_every``).

    ``hooks`` run between chunks (``Hook``): those that change the state before the chunk's
    checkpoint, the others after it. ``stop_after_chunks`` ends early after that many chunks (as
    if killed after a checkpoint); used by tests of resuming. ``until(end)`` true after a chunk
    ends the run there, with a checkpoint (a progressive stage whose success stopped rising).
    Raises ``TrainingDiverged`` when a
    chunk goes non-finite; a new run that fails before its first checkpoint leaves no folder.
    """
    if cfg.resume:
        cfg = _resumed(cfg)
        run_dir = Path(cfg.resume)
    if cfg.init_from:
        check_init_from(cfg.init_from)
    if cfg.resume:  # after init_from's: the clips a resumed run trained on are its own
        use_recorded_data(run_dir)
    mesh = make_mesh()
    _check_sizes(cfg, mesh.size)
    learner = make_learner(cfg)  # before the run folder exists: bad clips or settings leave nothing behind
    run_dir = Path(run_dir) if run_dir is not None else new_run_dir(experiment)
    phys = learner.env.physics
    backend = {
        "backend": phys.name,
        "device": jax.default_backend(),
        "devices": mesh.size,
        **({"threads": phys.nthread} if phys.name == "mujoco" else {}),
    }
    if progress:
        print(f"physics backend: {phys.name} ({', '.join(f'{k} {v}' for k, v in backend.items() if k != 'backend')})")
    ts = shard_state(learner.init(jax.random.PRNGKey(cfg.seed)), mesh)
    if cfg.init_from:  # before the run folder exists: an entry that does not fit leaves nothing behind
        ts = init_from(learner, ts, cfg.init_from)
        if progress:
            print(f"init_from {cfg.init_from}: starting at iteration {int(ts.iteration)}")
    if cfg.decoder_from and not cfg.resume and not cfg.init_from:
        ts = transfer_decoder(learner, ts, cfg.decoder_from)
        if progress:
            print(f"decoder_from {cfg.decoder_from}: its experts and body statistics, a new encoder")
    fresh = not cfg.resume and not run_dir.exists()
    try:
        _record_config(run_dir, experiment, cfg, {"physics": backend, "data": str(data_dir().absolute())})
        return _run(
            experiment,
            cfg,
            learner,
            mesh,
            ts,
            run_dir,
            fresh,
            progress,
            tensorboard,
            stop_after_chunks,
            on_chunk,
            hooks,
            until,
        )
    except BaseException:
        if fresh:
            _remove_unfinished(run_dir)
        raise


def _restore_resumed(run_dir: Path, ts: TrainState) -> TrainState:
    """A resumed run's state: its newest checkpoint that can be read (damaged newer ones are set
    aside in ``damaged/``, one line each), or ``ts`` when it has none; its log trimmed to it."""
    if ckpt.has_checkpoint(run_dir):
        mgr, lines = ckpt.manager(run_dir), []
        try:
            ts, _, damaged = ckpt.restore_newest(mgr, ts, say=lines.append, doing="resuming from")
        finally:
            mgr.close()
        for line, dest in zip(lines, ckpt.set_aside(run_dir, damaged)):
            print(f"{line} (moved to {dest})", file=sys.stderr)
    _trim_metrics(run_dir / "metrics.jsonl", int(ts.iteration))
    return ts


def _last_wall(metrics_path: Path) -> float:
    """The ``wall_s`` of a log's last row that has one (0: none)."""
    if not metrics_path.is_file():
        return 0.0
    wall = 0.0
    with open(metrics_path) as f:
        for line in f:
            try:
                wall = float(json.loads(line).get("wall_s", wall))
            except (ValueError, AttributeError):
                continue
    return wall


def _run(
    experiment, cfg, learner, mesh, ts, run_dir, fresh, progress, tensorboard, stop_after_chunks, on_chunk, hooks, until
):
    """The chunk loop of ``train`` (its arguments), in a run folder whose config is written
    (``fresh``: a folder this call created)."""
    if cfg.resume:
        ts = _restore_resumed(run_dir, ts)
    mgr = ckpt.manager(run_dir)
    metrics_path = run_dir / "metrics.jsonl"
    start = int(ts.iteration)
    if start >= cfg.iterations and progress:
        print(f"{run_dir}: at iteration {start} of {cfg.iterations}, nothing to train (iterations=N continues it)")
    chunk_fn = make_train_chunk(learner, mesh, cfg.chunk, ts)
    backends.WARNINGS.take()  # warnings of building the env are not the run's
    writer = None
    if tensorboard:
        from tensorboardX import SummaryWriter

        writer = SummaryWriter(str(run_dir / "tb"))
    from tqdm import tqdm

    bar = tqdm(
        total=cfg.iterations, initial=start, unit="it", disable=not progress, dynamic_ncols=True, desc=experiment
    )
    history: list[dict] = []
    chunks = 0
    # Wall time of the training so far, evaluations and checkpoints included (a resumed run
    # continues its count), for the time to a result (``evaluation/time_to_result.py``).
    wall0, started = _last_wall(metrics_path), time.perf_counter()
    try:
        while int(ts.iteration) < cfg.iterations:
            # Throughput of the compiled chunk alone (the first includes its compilation), not of
            # the logging, checkpoints and evaluations between chunks.
            t0 = time.perf_counter()
            ts, m = chunk_fn(ts)
            m = jax.device_get(m)
            t1 = time.perf_counter()
            sps = cfg.chunk * cfg.samples_per_iteration / (t1 - t0)
            it0 = int(ts.iteration) - cfg.chunk
            warned = log_physics_warnings(run_dir, int(ts.iteration))
            rows = []
            with open(metrics_path, "a") as f:
                for i in range(cfg.chunk):
                    row = {
                        "iteration": it0 + i + 1,
                        "samples": (it0 + i + 1) * cfg.samples_per_iteration,
                        "steps_per_s": sps,
                        "wall_s": wall0 + (t0 - started) + (t1 - t0) * (i + 1) / cfg.chunk,
                        **_scalars(m, i),
                    }
                    if i == cfg.chunk - 1:  # the chunk's count, on its last row
                        row["physics/warnings"] = float(warned)
                    f.write(json.dumps(row) + "\n")
                    rows.append(row)
                    if writer is not None:
                        for k, v in row.items():
                            if k != "iteration" and math.isfinite(v):  # a non-finite row stops the run below
                                writer.add_scalar(k, v, row["iteration"])
            history.extend(rows)
            chunks += 1
            problem = divergence(run_dir, rows, ts, mgr.latest_step(), fresh)
            if problem is not None:  # before hooks and the checkpoint: the last one stays good
                raise TrainingDiverged(problem)
            last = history[-1]
            post = {"sps": f"{sps:,.0f}"}
            post.update({k.split("/")[1][:6]: f"{v:.3f}" for k, v in last.items() if k.startswith("reward/")})
            post["pi"] = f"{last.get('ppo/policy_loss', 0):.3f}"
            post["v"] = f"{last.get('ppo/value_loss', 0):.3f}"
            bar.set_postfix(post, refresh=False)
            bar.update(cfg.chunk)
            done = int(ts.iteration) >= cfg.iterations
            end = ChunkEnd(
                run_dir=run_dir,
                iteration=int(ts.iteration),
                chunks=chunks,
                done=done,
                last=last,
                log=functools.partial(_log_row, metrics_path, writer, last),
                say=bar.write,
            )
            for hook in hooks:
                if hook.before_checkpoint and hook.due(cfg, end):
                    ts = hook.run(learner, ts, end)
            stop = until is not None and until(end)
            if done or stop or chunks % cfg.checkpoint_every == 0 or stop_after_chunks == chunks:
                ckpt.save(mgr, int(ts.iteration), ts)
            for hook in hooks:
                if not hook.before_checkpoint and hook.due(cfg, end):
                    hook.run(learner, ts, end)
            if on_chunk is not None:
                on_chunk(int(ts.iteration), last)
            if stop or (stop_after_chunks is not None and chunks >= stop_after_chunks):
                break
    finally:
        bar.close()
        if writer is not None:
            writer.close()
        mgr.close()
    return RunResult(run_dir=run_dir, state=ts, metrics=history)
