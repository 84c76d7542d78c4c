"""Tasks a scene can run, by name (``EnvConfig.task.name``); see ``tasks/base.py``.

Register a new one with ``TASKS["name"] = MyTask`` (a ``Task`` subclass taking ``(cfg, env)``).
"""

from jaxmotion.tasks.base import (AimConfig, BoxingConfig, FencingConfig, HeadingConfig,  # noqa: F401
                                  JuggleConfig, LocationConfig, Task, TaskConfig, TaskStep, TennisConfig, TrackConfig,
                                  combine_weights)
from jaxmotion.tasks.bout import Boxing, Fencing
from jaxmotion.tasks.juggle import JuggleLocation
from jaxmotion.tasks.location import AimLocation, Heading, Location
from jaxmotion.tasks.tennis import Tennis
from jaxmotion.tasks.track import Track

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


def make_task(cfg: TaskConfig, env) -> Task:
    """The task ``cfg.name`` for a scene; a clear error lists the registered names."""
    try:
        cls = TASKS[cfg.name]
    except KeyError:
        raise ValueError(f"unknown task {cfg.name!r}; registered tasks: {sorted(TASKS)}") from None
    return cls(cfg, env)
