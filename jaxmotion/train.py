"""``python -m jaxmotion.train <experiment> [key=value ...]``: train, log, checkpoint, resume.

The driver is ``training/run.py``; this entry point loads the experiment, applies the overrides
and adds the hooks that evaluation provides (periodic evaluation, hard-negative mining).
``resume=<run-folder>`` continues a killed run with its saved settings (only ``iterations=`` and
``checkpoint_every=`` may change; the experiment name is the run's); ``init_from=<run-or-pretrained-folder>``
starts a new run from another run's parameters and statistics. An experiment with
``progressive.primitives`` > 0 runs the progressive pipeline (``training/progressive.py``).
``JAXMOTION_DISTRIBUTED=1`` calls ``jax.distributed.initialize()`` first, for several hosts (not yet
exercised on a real cluster).
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import jax

from jaxmotion import config as C
from jaxmotion.config.errors import cli_errors
from jaxmotion.evaluation.imitation import PERIODIC_EVAL
from jaxmotion.evaluation.tracking import MINING
from jaxmotion.training import checkpoint as ckpt
from jaxmotion.training import progressive, run
from jaxmotion.training.learner import TrainConfig

HOOKS = (MINING, PERIODIC_EVAL)
"""Between-chunk work every run gets; each hook decides from the config whether it is due."""
RESUMABLE = ("resume", "iterations", "checkpoint_every")
"""The settings ``resume=`` may be given with: a resumed run keeps all others."""


def override_key(item: str) -> str:
    """The key of a ``key=value`` override (``ppo.gamma=0.9`` -> ``ppo.gamma``)."""
    return item.partition("=")[0].strip()


def resume_target(overrides: list[str]) -> str:
    """The run folder the last ``resume=`` override names (quotes stripped), or empty."""
    values = [item.partition("=")[2].strip() for item in overrides if override_key(item) == "resume"]
    value = values[-1] if values else ""
    return value[1:-1] if len(value) >= 2 and value[0] == value[-1] and value[0] in "\"'" else value


def resumed_config(name: str, overrides: list[str]) -> tuple[str, TrainConfig]:
    """(experiment, config) of ``resume=<run>``: the run's saved config with the given
    ``iterations=`` / ``checkpoint_every=`` applied; any other setting is a ``ConfigError``
    (a resumed run cannot change what it trains). The experiment is the run's, whatever ``name``
    says (``make train`` passes its default ``EXP``)."""
    run_dir = resume_target(overrides)
    keys = dict.fromkeys(override_key(item) for item in overrides if "=" in item)
    others = [k for k in keys if k not in RESUMABLE]
    if others:
        raise C.ConfigError(
            f"resume={run_dir} keeps the run's saved settings: {', '.join(others)} cannot change "
            f"(only iterations= and checkpoint_every= can; init_from={run_dir} starts a new run from it)"
        )
    experiment, saved = ckpt.read_config(Path(run_dir), TrainConfig)
    if experiment != name:
        print(f"resume={run_dir}: a run of experiment {experiment} (not {name}); resuming it", file=sys.stderr)
    return experiment, C.apply_overrides(saved, overrides)


def train(experiment: str, cfg: TrainConfig, run_dir: Path | None = None, **kwargs) -> run.RunResult:
    """``training.run.train`` with the evaluation hooks (same arguments)."""
    return run.train(experiment, cfg, run_dir, hooks=HOOKS, **kwargs)


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
    if resume_target(overrides):
        name, cfg = resumed_config(name, overrides)
    else:
        cfg = C.apply_overrides(C.load_experiment(name), overrides)
    if cfg.progressive.primitives:
        root = progressive.run_pipeline(name, cfg, train)
        print(f"run folder: {root}")
        return 0
    result = train(name, cfg)
    print(f"run folder: {result.run_dir}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
