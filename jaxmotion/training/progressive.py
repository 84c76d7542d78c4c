"""Progressive primitives and their composer as one resumable pipeline (PHC §3.2, Alg. 1).

``make train EXP=<exp>`` with ``progressive.primitives`` = K > 0 runs, in one run folder:

1. ``primitive_1/``: the experiment on all its clips (from ``init_from`` if given);
2. ``primitive_k/`` (k = 2..K): starts from ``primitive_{k-1}``'s latest checkpoint (policy,
   critic, discriminator, statistics: "kept and fine-tuned, never reinitialised") and trains on
   the clips that primitive failed in its last mining passes; no stage when none failed;
3. ``recovery/`` (with ``progressive.recovery_iterations``): the fail-state recovery primitive
   (``tasks/recovery.py``), from the last primitive, on ``progressive.recovery_clips``;
4. ``composer/``: a composer (``nets/composer.py``) over the frozen primitives (the recovery one
   included) on all the clips, PPO training only the composer; with a recovery primitive the
   composer trains with fallen and far starts and recovery episodes too (PHC §3.2).

The imitation primitives train with the experiment's recovery settings off, the recovery
primitive and the composer with them on.

A primitive stage ends ("is frozen") when its success rate on its own clips, measured by the
run's hard-negative mining passes (``evaluation.tracking.MINING``: every clip once from t = 0),
has not risen for ``progressive.patience`` passes, reaches 1, or after
``progressive.stage_iterations``. The next stage's clips are those any of the passes the rule
judged (the last ``patience`` + 1) failed: which clip fails varies from pass to pass, and the
authors' code takes the union of the failures of its last few evaluations as well. Their version
is a sequence of manual steps.
Departure: every stage's discriminator keeps the experiment's reference clips (the motion prior
stays the whole set), only the clips episodes start on and mining evaluates change.

``pipeline.json`` records every stage (clips, iterations, success per mining pass, failed
clips) as it ends; ``resume=<pipeline folder>`` continues the stage that was running (from its
newest checkpoint) and then the rest. ``python -m jaxmotion.eval <pipeline folder>`` evaluates
its last stage (``runs.load_run``).
"""

from __future__ import annotations

import dataclasses
import json
from collections.abc import Callable, Sequence
from pathlib import Path

from jaxmotion.training import checkpoint as ckpt
from jaxmotion.config.checks import report
from jaxmotion.training.hparams import ProgressiveConfig, TrainConfig, progressive_problems
from jaxmotion.training.runs import PIPELINE_FILE, new_run_dir

HARD_FILE = "hard_clips.json"  # evaluation.tracking.HARD_FILE, which this layer may not import


def plateaued(rates: Sequence[float], patience: int) -> bool:
    """Whether a stage's success has stopped rising: its last mining pass tracked every clip, or
    its last ``patience`` passes did not beat the best pass before them."""
    if rates and rates[-1] >= 1.0:
        return True
    if len(rates) <= patience:
        return False
    return max(rates[-patience:]) <= max(rates[:-patience])


def mining_rates(run_dir: Path) -> list[float]:
    """The success rate of every mining pass logged in ``run_dir/metrics.jsonl``, in order."""
    path = Path(run_dir) / "metrics.jsonl"
    rates = []
    if path.exists():
        for line in path.read_text().splitlines():
            try:
                row = json.loads(line)
            except ValueError:  # a line cut short by a kill
                continue
            if isinstance(row, dict) and "mining/success_rate" in row:
                rates.append(float(row["mining/success_rate"]))
    return rates


def failed_clips(run_dir: Path, passes: int = 1) -> list[str]:
    """The clips any of the stage's last ``passes`` mining passes failed (``hard_clips.json``),
    in the order they first failed; none when no pass ran (the file is missing)."""
    path = Path(run_dir) / HARD_FILE
    if not path.exists():
        return []
    doc = json.loads(path.read_text())
    runs = [p["failed"] for p in doc.get("passes", [])[-passes:]] or [doc["failed"]]
    return list(dict.fromkeys(c for failed in runs for c in failed))


def latest_step(run_dir: Path) -> int:
    """The iteration of a run folder's newest checkpoint (0 if it has none)."""
    d = Path(run_dir) / "checkpoints"
    steps = [int(p.name) for p in d.iterdir() if p.name.isdigit()] if d.is_dir() else []
    return max(steps, default=0)


def with_recovery(cfg: TrainConfig, on: bool) -> TrainConfig:
    """``cfg`` with the tracker's fail-state recovery (``env.task.track.recovery``) on or off."""
    track = cfg.env.task.track
    track = dataclasses.replace(track, recovery=dataclasses.replace(track.recovery, enabled=on))
    return dataclasses.replace(
        cfg, env=dataclasses.replace(cfg.env, task=dataclasses.replace(cfg.env.task, track=track))
    )


def primitive_config(
    base: TrainConfig, clips: Sequence[str], init_from: str, start: int, iterations: int | None = None
) -> TrainConfig:
    """A primitive stage: ``base`` starting its episodes on ``clips``, from ``init_from`` (empty:
    from scratch), for ``iterations`` (default ``base.progressive.stage_iterations``) after ``start``."""
    env = dataclasses.replace(base.env, init_motions=tuple(clips))
    n = base.progressive.stage_iterations if iterations is None else iterations
    return dataclasses.replace(
        base, env=env, init_from=init_from, resume="", iterations=start + n, progressive=ProgressiveConfig()
    )


def composer_config(base: TrainConfig, primitives: Sequence[str]) -> TrainConfig:
    """The composer stage: ``base`` on all its clips with a composer over ``primitives``."""
    return dataclasses.replace(
        base,
        primitives=tuple(primitives),
        init_from="",
        resume="",
        iterations=base.progressive.composer_iterations,
        progressive=ProgressiveConfig(),
    )


def _read_state(root: Path) -> dict:
    path = root / PIPELINE_FILE
    return json.loads(path.read_text()) if path.exists() else {"stages": {}, "final": None}


def _write_state(root: Path, state: dict) -> None:
    tmp = root / (PIPELINE_FILE + ".tmp")
    tmp.write_text(json.dumps(state, indent=2))
    tmp.replace(root / PIPELINE_FILE)


def run_pipeline(experiment: str, cfg: TrainConfig, train: Callable, say: Callable[[str], None] = print) -> Path:
    """Runs (or, with ``cfg.resume`` naming a pipeline folder, continues) the pipeline of ``cfg``;
    ``train(experiment, cfg, run_dir=, until=)`` trains one stage (``jaxmotion.train.train``).
    Returns the pipeline folder."""
    pc = cfg.progressive
    report(cfg, progressive_problems(cfg))
    if cfg.resume:
        root = Path(cfg.resume)
    else:
        root = new_run_dir(experiment)
        ckpt.write_config(root, experiment, cfg)
    state = _read_state(root)
    base = dataclasses.replace(cfg, resume="", init_from="")
    recovering = pc.recovery_iterations > 0
    plain = with_recovery(base, False) if base.env.task.name == "track" else base
    clips, prev = list(cfg.env.init_motions), cfg.init_from
    done: list[str] = []
    for k in range(1, pc.primitives + 1):
        name = f"primitive_{k}"
        rec = state["stages"].get(name)
        if rec is None:
            if not clips:
                say(f"{name}: no failed clips left; no further primitive")
                break
            start = latest_step(prev) if prev else 0
            rec = {"clips": clips, "init_from": prev, "start": start, "status": "running"}
            state["stages"][name] = rec
            _write_state(root, state)
        if rec["status"] != "done":
            _train_stage(
                experiment,
                root / name,
                primitive_config(plain, rec["clips"], rec["init_from"], rec["start"]),
                train,
                pc,
            )
            rec.update(_outcome(root / name, pc.patience + 1))
            rec["status"] = "done"
            state["final"] = name
            _write_state(root, state)
            say(f"{name}: {_summary(rec)}")
        done.append(str(root / name))
        prev, clips = str(root / name), rec["failed"]
    if recovering and done:
        rec = state["stages"].get("recovery")
        if rec is None:
            clips = list(pc.recovery_clips or cfg.env.init_motions)
            rec = {"clips": clips, "init_from": done[-1], "start": latest_step(done[-1]), "status": "running"}
            state["stages"]["recovery"] = rec
            _write_state(root, state)
        if rec["status"] != "done":
            stage = primitive_config(
                with_recovery(base, True), rec["clips"], rec["init_from"], rec["start"], pc.recovery_iterations
            )
            _train_stage(experiment, root / "recovery", stage, train, pc, plateau=False)
            rec.update({"end": latest_step(root / "recovery"), "status": "done"})
            state["final"] = "recovery"
            _write_state(root, state)
            say(f"recovery: to iteration {rec['end']}")
        done.append(str(root / "recovery"))
    if pc.composer_iterations and len(done) >= 2:
        rec = state["stages"].setdefault("composer", {"primitives": done, "status": "running"})
        if rec["status"] != "done":
            _write_state(root, state)
            stage = composer_config(with_recovery(base, True) if recovering else plain, rec["primitives"])
            _train_stage(experiment, root / "composer", stage, train, pc)
            rec.update(_outcome(root / "composer", pc.patience + 1))
            rec["status"] = "done"
            state["final"] = "composer"
            _write_state(root, state)
            say(f"composer: {_summary(rec)}")
    return root


def _train_stage(
    experiment: str, run_dir: Path, cfg: TrainConfig, train: Callable, pc: ProgressiveConfig, plateau: bool = True
) -> None:
    """Trains (or resumes, if it has a checkpoint) one stage until it ends or, with ``plateau``,
    plateaus (judged after the chunks that ran a mining pass, from the stage's log)."""

    def until(end) -> bool:
        return plateau and "mining/success_rate" in end.last and plateaued(mining_rates(run_dir), pc.patience)

    if ckpt.has_checkpoint(run_dir):
        train(experiment, dataclasses.replace(cfg, resume=str(run_dir), init_from=""), until=until)
    else:
        train(experiment, cfg, run_dir=run_dir, until=until)


def _outcome(run_dir: Path, passes: int) -> dict:
    rates = mining_rates(run_dir)
    return {"end": latest_step(run_dir), "success": rates, "failed": failed_clips(run_dir, passes)}


def _summary(rec: dict) -> str:
    rates = ", ".join(f"{r:.2f}" for r in rec["success"]) or "no mining pass"
    return f"to iteration {rec['end']}, success per mining pass {rates}; failed: {len(rec['failed'])} clips"
