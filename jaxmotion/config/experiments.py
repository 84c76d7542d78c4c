"""Experiment files: ``experiments/<name>.py`` each defining ``config()``.

Names may contain ``/`` and ``+`` (``composite/chest_open+squat``). Files and folders starting
with ``_`` or ``.`` are helpers, not experiments. ``$JAXMOTION_EXPERIMENTS`` points at another
experiments folder.
"""

from __future__ import annotations

import dataclasses
import difflib
import importlib.util
import os
import pathlib
import re
import sys
import types
from collections.abc import Sequence
from typing import Any

from jaxmotion.config.errors import ConfigError
from jaxmotion.config.overrides import apply_overrides

ENV_EXPERIMENTS = "JAXMOTION_EXPERIMENTS"


def experiments_root() -> pathlib.Path:
    """The experiments folder: ``$JAXMOTION_EXPERIMENTS``, else ``<repo>/experiments``."""
    env = os.environ.get(ENV_EXPERIMENTS)
    if env:
        return pathlib.Path(env).expanduser().resolve()
    return pathlib.Path(__file__).resolve().parents[2] / "experiments"


def list_experiments(root: pathlib.Path | str | None = None) -> list[str]:
    """Names of the experiments under ``root``, sorted.

    Args:
        root: the experiments folder; defaults to ``experiments_root()``.

    Returns:
        Paths of ``**/*.py`` relative to ``root`` without the suffix, in POSIX form; files and
        folders whose name starts with ``_`` or ``.`` (helpers, ``__pycache__``) are left out.
    """
    root = pathlib.Path(root) if root is not None else experiments_root()
    if not root.is_dir():
        return []
    names = []
    for path in root.rglob("*.py"):
        rel = path.relative_to(root)
        if any(part.startswith(("_", ".")) for part in rel.parts):
            continue
        names.append(rel.with_suffix("").as_posix())
    return sorted(names)


def _experiment_path(name: str, root: pathlib.Path) -> pathlib.Path:
    name = name.strip().removesuffix(".py")
    parts = pathlib.PurePosixPath(name).parts
    if not name or name.startswith("/") or any(p in ("..", ".") for p in parts):
        raise ConfigError(f"bad experiment name {name!r}: use a path relative to {root}")
    return root.joinpath(*parts[:-1], parts[-1] + ".py")


def _module_name(name: str) -> str:
    safe = name.replace("/", "__").replace("+", "_plus_")
    return "jaxmotion_experiment_" + re.sub(r"\W", "_", safe)


def load_experiment(name: str, root: pathlib.Path | str | None = None) -> Any:
    """Loads ``<root>/<name>.py`` and returns its ``config()``.

    Args:
        name: the experiment name, e.g. ``smoke`` or ``composite/chest_open+squat``.
        root: the experiments folder; defaults to ``experiments_root()``.

    Returns:
        The frozen dataclass the file's ``config()`` returns.

    Raises:
        ConfigError: no such experiment (the message lists those available and the closest),
            or the file defines no ``config()``, or ``config()`` returns no dataclass.
    """
    root = pathlib.Path(root) if root is not None else experiments_root()
    path = _experiment_path(name, root)
    if not path.is_file():
        available = list_experiments(root)
        close = difflib.get_close_matches(name, available, n=1)
        hint = f" (did you mean {close[0]!r}?)" if close else ""
        listing = ", ".join(available) if available else "none"
        raise ConfigError(f"unknown experiment {name!r}{hint}: no file {path}. Available in {root}: {listing}")
    # Experiment files may import shared helpers (``_common.py``) from the experiments folder.
    if str(root) not in sys.path:
        sys.path.insert(0, str(root))
    module = _exec_file(path, _module_name(name))
    factory = getattr(module, "config", None)
    if not callable(factory):
        raise ConfigError(f"experiment file {path} defines no config() function")
    cfg = factory()
    if not (dataclasses.is_dataclass(cfg) and not isinstance(cfg, type)):
        raise ConfigError(f"config() in {path} returned a {type(cfg).__name__}, not a dataclass instance")
    return cfg


def _exec_file(path: pathlib.Path, module_name: str) -> types.ModuleType:
    """Executes a Python file as a fresh module registered in ``sys.modules``.

    Registration lets dataclasses defined in the file resolve their (string) annotations.
    """
    spec = importlib.util.spec_from_file_location(module_name, path)
    if spec is None or spec.loader is None:
        raise ConfigError(f"cannot load experiment file {path}")
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module
    try:
        spec.loader.exec_module(module)
    except BaseException:
        sys.modules.pop(module_name, None)
        raise
    return module


def load(name: str, overrides: Sequence[str] = (), root: pathlib.Path | str | None = None) -> Any:
    """``load_experiment`` followed by ``apply_overrides``: what ``make train`` needs."""
    return apply_overrides(load_experiment(name, root), list(overrides))
