"""The training driver: Python between compiled chunks (``loop.make_train_chunk``).

It shows a progress bar, appends ``metrics.jsonl``, writes TensorBoard events and orbax
checkpoints between chunks, and runs the hooks a run asks for (periodic evaluation, hard-negative
mining) without knowing what they do. ``resume=<run-folder>`` continues a killed run from its latest
checkpoint; on CPU the result is identical to an uninterrupted run (same chunking, the RNG lives in
the checkpointed state).
"""

from __future__ import annotations

import dataclasses
import functools
import json
import time
from pathlib import Path
from collections.abc import Callable, Sequence

import jax
import numpy as np

from jaxmotion.training import checkpoint as ckpt
from jaxmotion.training.learner import TrainConfig, TrainState
from jaxmotion.training.loop import make_mesh, make_train_chunk, shard_state
from jaxmotion.training.runs import check_init_from, init_from, make_learner, new_run_dir


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


def _trim_metrics(path: Path, upto: int) -> None:
    """Drops log lines past ``upto`` iterations (written after the checkpoint a resume starts from)."""
    if not path.exists():
        return
    keep = [line for line in path.read_text().splitlines() if line.strip() and json.loads(line)["iteration"] <= upto]
    tmp = path.with_suffix(".tmp")
    tmp.write_text("".join(line + "\n" for line in keep))
    tmp.replace(path)


def train(
    experiment: str,
    cfg: TrainConfig,
    run_dir: Path | None = None,
    progress: bool = True,
    tensorboard: bool = True,
    stop_after_chunks: int | None = None,
    on_chunk: Callable[[int, dict], None] | None = None,
    hooks: Sequence[Hook] = (),
) -> RunResult:
    """Trains ``cfg`` into ``run_dir`` (resuming when ``cfg.resume`` names a run folder).

    ``hooks`` run between chunks (``Hook``): those that change the state before the chunk's
    checkpoint, the others after it. ``stop_after_chunks`` ends early after that many chunks (as
    if killed after a checkpoint); used by tests of resuming.
    """
    if cfg.resume:
        run_dir = Path(cfg.resume)
        _, saved = ckpt.read_config(run_dir, TrainConfig)
        # A resumed run keeps its saved settings; only the length and bookkeeping may change.
        cfg = dataclasses.replace(
            saved, iterations=cfg.iterations, resume=cfg.resume, checkpoint_every=cfg.checkpoint_every
        )
    if cfg.init_from:
        check_init_from(cfg.init_from)
    learner = make_learner(cfg)  # before the run folder exists: bad clips or settings leave nothing behind
    run_dir = Path(run_dir) if run_dir is not None else new_run_dir(experiment)
    phys = learner.env.physics
    backend = {
        "backend": phys.name,
        "device": jax.default_backend(),
        **({"threads": phys.nthread} if phys.name == "mujoco" else {}),
    }
    if progress:
        print(f"physics backend: {phys.name} ({', '.join(f'{k} {v}' for k, v in backend.items() if k != 'backend')})")
    mesh = make_mesh()
    if cfg.ppo.num_envs % mesh.size:
        raise ValueError(f"num_envs ({cfg.ppo.num_envs}) must be divisible by the device count ({mesh.size})")
    ts = shard_state(learner.init(jax.random.PRNGKey(cfg.seed)), mesh)
    if cfg.init_from:  # before the run folder exists: an entry that does not fit leaves nothing behind
        ts = init_from(learner, ts, cfg.init_from)
        if progress:
            print(f"init_from {cfg.init_from}: starting at iteration {int(ts.iteration)}")
    if not cfg.resume:
        ckpt.write_config(run_dir, experiment, dataclasses.replace(cfg, resume=""), resolved={"physics": backend})
    mgr = ckpt.manager(run_dir)
    metrics_path = run_dir / "metrics.jsonl"
    if cfg.resume and mgr.latest_step() is not None:
        ts, step = ckpt.restore(mgr, ts)
        _trim_metrics(metrics_path, step)
    start = int(ts.iteration)
    if cfg.iterations % cfg.chunk:
        raise ValueError(f"iterations ({cfg.iterations}) must be a multiple of chunk ({cfg.chunk})")
    chunk_fn = make_train_chunk(learner, mesh, cfg.chunk, ts)
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
    while int(ts.iteration) < cfg.iterations:
        # Throughput of the compiled chunk alone (the first includes its compilation), not of
        # the logging, checkpoints and evaluations between chunks.
        t0 = time.perf_counter()
        ts, m = chunk_fn(ts)
        m = jax.device_get(m)
        sps = cfg.chunk * cfg.samples_per_iteration / (time.perf_counter() - t0)
        it0 = int(ts.iteration) - cfg.chunk
        with open(metrics_path, "a") as f:
            for i in range(cfg.chunk):
                row = {
                    "iteration": it0 + i + 1,
                    "samples": (it0 + i + 1) * cfg.samples_per_iteration,
                    "steps_per_s": sps,
                    **_scalars(m, i),
                }
                f.write(json.dumps(row) + "\n")
                history.append(row)
                if writer is not None:
                    for k, v in row.items():
                        if k != "iteration":
                            writer.add_scalar(k, v, row["iteration"])
        chunks += 1
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
        if done or chunks % cfg.checkpoint_every == 0 or stop_after_chunks == chunks:
            ckpt.save(mgr, int(ts.iteration), ts)
        for hook in hooks:
            if not hook.before_checkpoint and hook.due(cfg, end):
                hook.run(learner, ts, end)
        if on_chunk is not None:
            on_chunk(int(ts.iteration), last)
        if stop_after_chunks is not None and chunks >= stop_after_chunks:
            break
    bar.close()
    if writer is not None:
        writer.close()
    mgr.close()
    return RunResult(run_dir=run_dir, state=ts, metrics=history)
