"""Evaluators, one per kind of run, each with its own flags and metrics.

A task names its evaluator (``Task.evaluator``); ``python -m jaxmotion.eval`` looks it up here.
An evaluator is a module with ``add_arguments(parser)`` (its own argument group) and
``run(args, experiment, cfg, learner, ts) -> exit status``. Register a new one with one line.
"""

from __future__ import annotations

from types import ModuleType

from jaxmotion.evaluation import bouts, imitation, tracking

EVALUATORS: dict[str, ModuleType] = {
    "imitation": imitation,
    "tracking": tracking,
    "bouts": bouts,
}


def evaluator_of(learner) -> ModuleType:
    """The evaluator of a learner's task (``Task.evaluator``)."""
    return EVALUATORS[learner.env.task.evaluator]
