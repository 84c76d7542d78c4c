"""``python -m jaxmotion.train <experiment> [key=value ...]``: train, log, checkpoint, resume.

Python only drives the compiled chunks (``loop.make_train_chunk``): it shows a progress bar,
appends ``metrics.jsonl``, writes TensorBoard events and orbax checkpoints between chunks.
``resume=<run-folder>`` continues a killed run from its latest checkpoint; on CPU the result is
identical to an uninterrupted run (same chunking, the RNG lives in the checkpointed state).
``JAXMOTION_DISTRIBUTED=1`` calls ``jax.distributed.initialize()`` first, for several hosts
(not yet exercised on a real cluster).
"""

from __future__ import annotations

import dataclasses
import json
import os
import sys
import time
from pathlib import Path
from typing import Callable

import jax
import numpy as np

from jaxmotion import checkpoint as ckpt
from jaxmotion import config as C
from jaxmotion.loop import make_mesh, make_train_chunk, shard_state
from jaxmotion.trainer import Learner, TrainConfig, TrainState
from jaxmotion.data import cli_errors


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
    keep = [l for l in path.read_text().splitlines() if l.strip() and json.loads(l)["iteration"] <= upto]
    tmp = path.with_suffix(".tmp")
    tmp.write_text("".join(l + "\n" for l in keep))
    tmp.replace(path)


def _log_eval(learner: Learner, ts: TrainState, cfg: TrainConfig, path: Path, last: dict, writer) -> None:
    """Appends one evaluation row (DTW error and coverage per group, episode length, fall rate) to the log."""
    from jaxmotion import eval as E  # eval imports this module's neighbours; keep startup light

    res = E.evaluate(learner, ts, cfg.eval_episodes)
    row = {"iteration": last["iteration"], "samples": last["samples"],
           "eval/episode_length_s": res["episode_length_s"], "eval/fall_rate": res["fall_rate"]}
    for g, m in res["groups"].items():
        row[f"eval/{g}/dtw_error_m"] = m["dtw_error_m_mean"]
        row[f"eval/{g}/dtw_error_world_m"] = m["dtw_error_world_m_mean"]
        if "coverage" in m:
            row[f"eval/{g}/coverage_m"] = m["coverage"]["error_m"]
            row[f"eval/{g}/coverage_within"] = m["coverage"]["within"]
    for k, v in res["task"].items():
        if isinstance(v, (int, float)):
            row[f"eval/task/{k}"] = v
    with open(path, "a") as f:
        f.write(json.dumps(row) + "\n")
    if writer is not None:
        for k, v in row.items():
            if k.startswith("eval/"):
                writer.add_scalar(k, v, row["iteration"])
    last.update(row)


def mines_after(iteration: int, cfg: TrainConfig) -> bool:
    """Whether hard negatives are mined after the chunk that ends at ``iteration``: every
    ``hard_negatives_every`` chunks counted in iterations, not in this process's chunks, the
    run's last chunk included, and before that chunk's checkpoint, so that a run stopped at a
    mining iteration and resumed mines and samples as the uninterrupted one (skipping the last
    chunk lost the mining at the 1000th iteration of a 1000-iteration run resumed to 3000)."""
    return bool(cfg.hard_negatives_every) and (iteration // cfg.chunk) % cfg.hard_negatives_every == 0


def new_run_dir(experiment: str, root: Path = Path("runs")) -> Path:
    stamp = time.strftime("%Y%m%d-%H%M%S")
    d = root / experiment / stamp
    n = 1
    while d.exists():
        d = root / experiment / f"{stamp}-{n}"
        n += 1
    return d


def train(experiment: str, cfg: TrainConfig, run_dir: Path | None = None, progress: bool = True,
          tensorboard: bool = True, stop_after_chunks: int | None = None,
          on_chunk: Callable[[int, dict], None] | None = None) -> RunResult:
    """Trains ``cfg`` into ``run_dir`` (resuming when ``cfg.resume`` names a run folder).

    ``stop_after_chunks`` ends early after that many chunks (as if killed after a checkpoint);
    used by tests of resuming.
    """
    if cfg.resume:
        run_dir = Path(cfg.resume)
        _, saved = ckpt.read_config(run_dir, TrainConfig)
        # A resumed run keeps its saved settings; only the length and bookkeeping may change.
        cfg = dataclasses.replace(saved, iterations=cfg.iterations, resume=cfg.resume,
                                  checkpoint_every=cfg.checkpoint_every)
    learner = Learner(cfg)  # before the run folder exists: bad clips or settings leave nothing behind
    run_dir = Path(run_dir) if run_dir is not None else new_run_dir(experiment)
    phys = learner.env.physics
    backend = {"backend": phys.name, "device": jax.default_backend(),
               **({"threads": phys.nthread} if phys.name == "mujoco" else {})}
    if progress:
        print(f"physics backend: {phys.name} ({', '.join(f'{k} {v}' for k, v in backend.items() if k != 'backend')})")
    if not cfg.resume:
        ckpt.write_config(run_dir, experiment, dataclasses.replace(cfg, resume=""), resolved={"physics": backend})
    mesh = make_mesh()
    if cfg.ppo.num_envs % mesh.size:
        raise ValueError(f"num_envs ({cfg.ppo.num_envs}) must be divisible by the device count ({mesh.size})")
    ts = shard_state(learner.init(jax.random.PRNGKey(cfg.seed)), mesh)
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
    bar = tqdm(total=cfg.iterations, initial=start, unit="it", disable=not progress, dynamic_ncols=True,
               desc=experiment)
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
                row = {"iteration": it0 + i + 1, "samples": (it0 + i + 1) * cfg.samples_per_iteration,
                       "steps_per_s": sps, **_scalars(m, i)}
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
        if mines_after(int(ts.iteration), cfg):
            from jaxmotion.track_eval import hard_negative_update
            ts, hard = hard_negative_update(learner, ts, run_dir)
            bar.write(f"hard negatives at iteration {int(ts.iteration)}: {len(hard)} of "
                      f"{learner.env.init_lib.num_clips} clips failed")
        if done or chunks % cfg.checkpoint_every == 0 or stop_after_chunks == chunks:
            ckpt.save(mgr, int(ts.iteration), ts)
        if cfg.eval_every and (chunks % cfg.eval_every == 0 or done):
            _log_eval(learner, ts, cfg, metrics_path, last, writer)
        if on_chunk is not None:
            on_chunk(int(ts.iteration), last)
        if stop_after_chunks is not None and chunks >= stop_after_chunks:
            break
    bar.close()
    if writer is not None:
        writer.close()
    mgr.close()
    return RunResult(run_dir=run_dir, state=ts, metrics=history)


@cli_errors
def main(argv: list[str] | None = None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    if not argv or argv[0] in ("-h", "--help"):
        print(__doc__)
        print("experiments:", ", ".join(C.list_experiments()))
        return 0 if argv else 2
    name, overrides = argv[0], argv[1:]
    if os.environ.get("JAXMOTION_DISTRIBUTED") == "1":
        # Several hosts: JAX finds the cluster (SLURM, Open MPI, or JAX_COORDINATOR_ADDRESS /
        # JAX_NUM_PROCESSES / JAX_PROCESS_ID); the mesh then spans every host's devices.
        jax.distributed.initialize()
    try:
        cfg = C.apply_overrides(C.load_experiment(name), overrides)
    except C.ConfigError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    result = train(name, cfg)
    print(f"run folder: {result.run_dir}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
