"""Tasks a scene can run, by name (``EnvConfig.task.name``); see ``tasks/base.py``.

A task is one module: the ``Task`` subclass and its settings (frozen dataclasses, declared in
``Task.settings``). Registering it is one line in ``TASKS``; ``TaskConfig`` gets a field for each
setting of every registered task, so ``env.task.<setting>.<key>=value`` overrides and run folders'
``config.json`` work for it without further edits.
"""

import dataclasses
from typing import Literal

from jaxmotion.config.errors import ConfigError
from jaxmotion.tasks.base import Task, TaskStep, combine_weights
from jaxmotion.tasks.bout import Boxing, BoxingConfig, Fencing, FencingConfig
from jaxmotion.tasks.juggle import JuggleConfig, JuggleLocation
from jaxmotion.tasks.location import AimConfig, AimLocation, Heading, HeadingConfig, Location, LocationConfig
from jaxmotion.tasks.tennis import Tennis, TennisConfig
from jaxmotion.tasks.track import Track, TrackConfig

TASKS: dict[str, type[Task]] = {
    "imitate": Task,
    "location": Location,
    "heading": Heading,
    "aim+location": AimLocation,
    "juggle+location": JuggleLocation,
    "track": Track,
    "boxing": Boxing,
    "fencing": Fencing,
    "tennis": Tennis,
}


def _task_config(tasks: dict[str, type[Task]]) -> type:
    fields: dict[str, type] = {}
    for cls in tasks.values():
        for field, settings in cls.settings:
            if fields.setdefault(field, settings) is not settings:
                raise TypeError(f"tasks declare two settings classes for TaskConfig.{field}")
    cls = dataclasses.make_dataclass(
        "TaskConfig",
        [("name", Literal[tuple(tasks)], dataclasses.field(default="imitate"))]
        + [(f, s, dataclasses.field(default=s())) for f, s in fields.items()],
        frozen=True,
        namespace={
            "__doc__": "Which task the scene runs (a name in ``TASKS``) and the settings of every "
            "registered task (``Task.settings``)."
        },
    )
    cls.__module__ = __name__
    return cls


TaskConfig = _task_config(TASKS)


def make_task(cfg: TaskConfig, env) -> Task:
    """The task ``cfg.name`` for a scene; a clear error lists the registered names."""
    try:
        cls = TASKS[cfg.name]
    except KeyError:
        raise ConfigError(f"env.task.name={cfg.name}: unknown task; registered tasks: {sorted(TASKS)}") from None
    return cls(cfg, env)


__all__ = [
    "TASKS",
    "Task",
    "TaskConfig",
    "TaskStep",
    "combine_weights",
    "make_task",
    "AimConfig",
    "BoxingConfig",
    "FencingConfig",
    "HeadingConfig",
    "JuggleConfig",
    "LocationConfig",
    "TennisConfig",
    "TrackConfig",
]
