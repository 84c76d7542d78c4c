"""``python -m jaxmotion.train <experiment> [key=value ...]``: train, log, checkpoint, resume.

The driver is ``training/run.py``; this entry point loads the experiment, applies the overrides
and adds the hooks that evaluation provides (periodic evaluation, hard-negative mining).
``resume=<run-folder>`` continues a killed run; ``init_from=<run-or-pretrained-folder>`` starts a
new run from another run's parameters and statistics. ``JAXMOTION_DISTRIBUTED=1`` calls
``jax.distributed.initialize()`` first, for several hosts (not yet exercised on a real cluster).
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
from jaxmotion.training import run
from jaxmotion.training.learner import TrainConfig

HOOKS = (MINING, PERIODIC_EVAL)
"""Between-chunk work every run gets; each hook decides from the config whether it is due."""


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
    cfg = C.apply_overrides(C.load_experiment(name), overrides)
    result = train(name, cfg)
    print(f"run folder: {result.run_dir}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
