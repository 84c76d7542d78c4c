"""Settings validation: ranges declared next to each field, rules between fields on their class.

A field declares what it accepts in its annotation (``typing.Annotated``; the override parser
reads only the type and ignores the markers)::

    num_envs: Annotated[int, Min(1)] = 512
    gamma: Annotated[float, Range(0, 1, hi_open=True)] = 0.95
    policy_hidden: Annotated[tuple[int, ...], Min(1)] = (1024, 512)   # bounds: every element
    speed_range: Annotated[tuple[float, float], Min(0, open=True), Ordered()] = (1.0, 1.0)
    max_qvel: Annotated[float, Min(0, open=True), AllowInf()] = 100.0
    loss: Literal["hinge", "lsgan", "bce"] = "hinge"

Every float must be finite unless its annotation says ``AllowInf()`` (NaN never passes), every
value must have its annotation's type, and a ``Literal`` must be one of its choices. A config
class states the rules between its fields in a method ``checks(self)`` that yields ``Problem``s
(called only when its fields passed). ``validate(cfg)`` walks a config tree (nested dataclasses,
tuples of them, mappings stored as pairs) and raises one ``ConfigError`` naming every problem by
its full dotted key: ``ppo.gamma=1.5: must be in [0, 1)``, ``env.groups[0].frames=0: must be ≥ 2``.
"""

from __future__ import annotations

import dataclasses
import difflib
import functools
import math
import os
import pathlib
import types
import typing
from collections.abc import Iterable, Mapping
from typing import Annotated, Any

from jaxmotion.config.errors import ConfigError

# --------------------------------------------------------------------------- markers


@dataclasses.dataclass(frozen=True)
class Min:
    """A number ≥ ``lo`` (``open=True``: > ``lo``)."""

    lo: float
    open: bool = False

    def problem(self, x: Any) -> str | None:
        ok = x > self.lo if self.open else x >= self.lo
        return None if ok else f"must be {'>' if self.open else '≥'} {_num(self.lo)}"


@dataclasses.dataclass(frozen=True)
class Max:
    """A number ≤ ``hi`` (``open=True``: < ``hi``)."""

    hi: float
    open: bool = False

    def problem(self, x: Any) -> str | None:
        ok = x < self.hi if self.open else x <= self.hi
        return None if ok else f"must be {'<' if self.open else '≤'} {_num(self.hi)}"


@dataclasses.dataclass(frozen=True)
class Range:
    """A number in [lo, hi]; either end may be open."""

    lo: float
    hi: float
    lo_open: bool = False
    hi_open: bool = False

    def problem(self, x: Any) -> str | None:
        above = x > self.lo if self.lo_open else x >= self.lo
        below = x < self.hi if self.hi_open else x <= self.hi
        if above and below:
            return None
        left, right = "(" if self.lo_open else "[", ")" if self.hi_open else "]"
        return f"must be in {left}{_num(self.lo)}, {_num(self.hi)}{right}"


@dataclasses.dataclass(frozen=True)
class NonEmpty:
    """A tuple, list or string with at least one element."""

    def problem(self, x: Any) -> str | None:
        return None if len(x) else "must not be empty"


@dataclasses.dataclass(frozen=True)
class Ordered:
    """A sequence in increasing order (``strict=True``: no two equal), e.g. a (lo, hi) range."""

    strict: bool = False

    def problem(self, x: Any) -> str | None:
        pairs = list(zip(x, x[1:]))
        ok = all(a < b for a, b in pairs) if self.strict else all(a <= b for a, b in pairs)
        return None if ok else f"must be in {'strictly ' if self.strict else ''}increasing order (low, high)"


@dataclasses.dataclass(frozen=True)
class AllowInf:
    """The float may be +-inf (a limit switched off); NaN is still refused."""


Count = Annotated[int, Min(1)]
"""A whole number of at least 1 (environments, steps, units, iterations)."""
Positive = Annotated[float, Min(0, open=True)]
NonNegative = Annotated[float, Min(0)]

ELEMENTWISE = (Min, Max, Range, AllowInf)
"""Marks that, on a tuple or list, bound each element: ``Annotated[tuple[float, float], Min(0)]``."""


@dataclasses.dataclass(frozen=True)
class Problem:
    """A broken rule: ``key`` (dotted, relative to the config whose ``checks`` found it; ``a[0].b``
    for tuple elements) and what is wrong with its value."""

    key: str
    message: str


# --------------------------------------------------------------------------- walking


def validate(cfg: Any, prefix: str = "", rules: bool = True) -> Any:
    """Checks every field of the config tree ``cfg`` and every class's ``checks()``.

    Args:
        cfg: a dataclass instance.
        prefix: the dotted key of ``cfg`` in a larger config (``env``), for the messages.
        rules: False checks the fields only, not the classes' ``checks()``.

    Returns:
        ``cfg`` unchanged.

    Raises:
        ConfigError: one line naming every problem, ``key=value: rule``, separated by ``;``.
    """
    found = problems(cfg, prefix, rules)
    if found:
        raise ConfigError("; ".join(found))
    return cfg


def problems(cfg: Any, prefix: str = "", rules: bool = True) -> list[str]:
    """What ``validate`` would complain about, one ``key=value: rule`` string each."""
    out: list[str] = []
    _walk_dataclass(cfg, prefix, out, rules)
    return out


def report(cfg: Any, found: Iterable[Problem], prefix: str = "") -> None:
    """Raises one ``ConfigError`` for ``Problem``s found in ``cfg`` (keys relative to it), if any."""
    lines = [_line(_join(prefix, p.key), _lookup(cfg, p.key), p.message) for p in found]
    if lines:
        raise ConfigError("; ".join(lines))


@functools.cache
def _hints(cls: type) -> dict[str, Any]:
    try:
        hints = typing.get_type_hints(cls, include_extras=True)
    except Exception as err:  # noqa: BLE001 - any failure to resolve is a broken config class
        raise ConfigError(f"cannot resolve the type annotations of {cls.__qualname__}: {err}") from err
    return {f.name: hints.get(f.name, Any) for f in dataclasses.fields(cls) if f.init}


def _walk_dataclass(obj: Any, key: str, out: list[str], rules: bool = True) -> None:
    before = len(out)
    for name, tp in _hints(type(obj)).items():
        _walk(getattr(obj, name), tp, _join(key, name), out, rules)
    checks = getattr(obj, "checks", None) if rules else None
    if len(out) == before and callable(checks):  # rules between fields trust the fields' ranges
        for p in checks():
            out.append(_line(_join(key, p.key), _lookup(obj, p.key), p.message))


def _walk(value: Any, tp: Any, key: str, out: list[str], rules: bool = True, inherited: tuple = ()) -> None:
    """Appends the problems of ``value`` (annotation ``tp``, with the bounds ``inherited`` from
    the sequence it is an element of) and of everything inside it."""
    tp, marks = _split_annotated(tp)
    marks = inherited + marks
    if _is_union(tp):
        args = typing.get_args(tp)
        if value is None and type(None) in args:
            return
        arms = [a for a in args if a is not type(None)]
        tp, extra = _split_annotated(next((a for a in arms if _fits(value, a)), arms[0]))
        marks = marks + extra
    wrong = _type_problem(value, tp)
    if wrong:
        out.append(_line(key, value, wrong))
        return
    if isinstance(value, float) and not math.isfinite(value) and (math.isnan(value) or AllowInf() not in marks):
        out.append(_line(key, value, "must be a finite number"))
        return
    seq = isinstance(value, (tuple, list))
    for mark in marks:
        msg = (
            None if seq and isinstance(mark, ELEMENTWISE) else mark.problem(value) if hasattr(mark, "problem") else None
        )
        if msg:
            out.append(_line(key, value, msg))
            return
    _walk_inside(value, tp, key, out, rules, tuple(m for m in marks if seq and isinstance(m, ELEMENTWISE)))


def _walk_inside(value: Any, tp: Any, key: str, out: list[str], rules: bool, inherited: tuple) -> None:
    """The elements of a tuple, list or dict, and the fields of a dataclass."""
    origin, args = typing.get_origin(tp), typing.get_args(tp)
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        _walk_dataclass(value, key, out, rules)
    elif origin in (dict, Mapping) and len(args) == 2:
        for k, v in value.items():
            _walk(v, args[1], f"{key}.{k}", out, rules)
    elif origin in (tuple, list):
        pair = _pair_types(tp)
        for i, item in enumerate(value):
            if pair is not None and isinstance(item, tuple) and len(item) == 2 and isinstance(item[0], str):
                _walk(item[1], pair, f"{key}.{item[0]}", out, rules, inherited)  # a mapping stored as pairs
            else:
                elem = args[i] if args and args[-1] is not Ellipsis else (args[0] if args else Any)
                _walk(item, elem, f"{key}[{i}]", out, rules, inherited)


def _type_problem(value: Any, tp: Any) -> str | None:
    """Why ``value`` is not of type ``tp`` (its outer level only), or None."""
    if tp is Any or tp is object:
        return None
    origin = typing.get_origin(tp)
    if origin is typing.Literal:
        return None if _in_choices(value, typing.get_args(tp)) else _choice_problem(value, typing.get_args(tp))
    if origin is not None:
        return _container_problem(value, origin, typing.get_args(tp))
    if tp is float:
        ok = isinstance(value, (int, float)) and not isinstance(value, bool)
    elif tp is int:
        ok = isinstance(value, int) and not isinstance(value, bool)
    elif isinstance(tp, type):
        ok = isinstance(value, tp)
    else:
        ok = True
    return None if ok else f"must be a {_type_name(tp)}, not a {type(value).__name__}"


def _container_problem(value: Any, origin: Any, args: tuple[Any, ...]) -> str | None:
    if origin in (dict, Mapping):
        return None if isinstance(value, Mapping) else f"must be a mapping, not a {type(value).__name__}"
    if origin in (tuple, list) and not isinstance(value, origin):  # a list would make the config unhashable
        return f"must be a {origin.__name__}, not a {type(value).__name__}"
    if origin is tuple and args and args[-1] is not Ellipsis and len(value) != len(args):
        return f"must have {len(args)} items, not {len(value)}"
    return None


def _choice_problem(value: Any, choices: tuple[Any, ...]) -> str:
    listed = ", ".join(repr(c) for c in choices)
    close = difflib.get_close_matches(str(value), [str(c) for c in choices], n=1)
    hint = f" (did you mean {close[0]!r}?)" if close else ""
    return f"must be one of {listed}{hint}"


def _in_choices(value: Any, choices: tuple[Any, ...]) -> bool:
    return any(value == c and type(value) is type(c) for c in choices)


def _fits(value: Any, tp: Any) -> bool:
    tp = _split_annotated(tp)[0]
    if typing.get_origin(tp) is typing.Literal:
        return _in_choices(value, typing.get_args(tp))
    return _type_problem(value, tp) is None


def _pair_types(tp: Any) -> Any | None:
    """The value type of a mapping stored as ``tuple[tuple[str, V], ...]``, else None."""
    args = typing.get_args(tp)
    if typing.get_origin(tp) is not tuple or len(args) != 2 or args[1] is not Ellipsis:
        return None
    pair, _ = _split_annotated(args[0])
    inner = typing.get_args(pair)
    if typing.get_origin(pair) is tuple and len(inner) == 2 and inner[0] is str:
        return inner[1]
    return None


def _split_annotated(tp: Any) -> tuple[Any, tuple[Any, ...]]:
    """``Annotated[T, m1, m2]`` -> ``(T, (m1, m2))``; anything else -> ``(tp, ())``."""
    if typing.get_origin(tp) is typing.Annotated:
        base, *marks = typing.get_args(tp)
        return base, tuple(marks)
    return tp, ()


def _is_union(tp: Any) -> bool:
    return typing.get_origin(tp) in (typing.Union, types.UnionType)


def _type_name(tp: Any) -> str:
    return {float: "number", int: "whole number", bool: "true/false", str: "string"}.get(
        tp, getattr(tp, "__name__", str(tp))
    )


# --------------------------------------------------------------------------- messages


def _join(prefix: str, name: str) -> str:
    return f"{prefix}.{name}" if prefix else name


def _lookup(obj: Any, key: str) -> Any:
    """The value at a relative dotted key (``groups[0].frames``) under ``obj``, or ``...``."""
    value = obj
    for part in key.replace("[", ".[").split("."):
        if not part:
            continue
        try:
            value = value[int(part[1:-1])] if part.startswith("[") else getattr(value, part)
        except (AttributeError, IndexError, TypeError, ValueError):
            return ...
    return value


def _line(key: str, value: Any, message: str) -> str:
    return f"{key}={show(value)}: {message}" if value is not ... else f"{key}: {message}"


def show(value: Any) -> str:
    """A value as a command line would write it: ``1.5``, ``nan``, ``64,64``, ``()``."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return f"{type(value).__name__}(...)"
    if isinstance(value, (tuple, list)):
        if not value:
            return "()"
        if any(dataclasses.is_dataclass(v) for v in value):
            return f"({len(value)} {type(value[0]).__name__})"
        text = ",".join(show(v) for v in value)
        return text if len(text) <= 60 else text[:57] + "..."
    if isinstance(value, (pathlib.PurePath, str)):
        return str(value) if str(value) else "''"
    return _num(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else str(value).lower()


def _num(x: float) -> str:
    return f"{x:g}" if isinstance(x, float) or abs(x) >= 10**12 else str(x)


# --------------------------------------------------------------------------- memory


def available_memory() -> int | None:
    """Bytes of host memory available now (``MemAvailable``, else free pages), or None."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return int(line.split()[1]) * 1024
    except (OSError, ValueError, IndexError):
        pass
    try:
        return os.sysconf("SC_AVPHYS_PAGES") * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, AttributeError):
        return None


def check_fits(key: str, count: int, bytes_each: int, what: str, available: int | None = None) -> None:
    """Raises a ``ConfigError`` naming ``key`` when ``count`` items of ``bytes_each`` bytes would
    not fit in ``available`` bytes (default: ``available_memory()``; unknown: no check)."""
    available = available_memory() if available is None else available
    need = count * bytes_each
    if available is not None and need > available:
        raise ConfigError(
            f"{key}={count}: {what} would need about {size(need)} ({size(bytes_each)} each), "
            f"more than the {size(available)} of memory available"
        )


def size(n: float) -> str:
    """Bytes, readable: ``512 B``, ``12.3 kB``, ``4.1 TB``."""
    for unit in ("B", "kB", "MB", "GB", "TB"):
        if abs(n) < 1000 or unit == "TB":
            return f"{n:.0f} {unit}" if unit == "B" else f"{n:.1f} {unit}"
        n /= 1000
    return f"{n:.1f} PB"  # pragma: no cover - the loop always returns


def check_output(flag: str, path: pathlib.Path) -> None:
    """``path`` can be written: not a folder, its folder made, a file opened there for writing
    (and removed again if it was not there)."""
    if path.is_dir():
        raise ConfigError(f"{flag}={path}: is a folder, not a file")
    above = next((p for p in path.parents if p.exists()), None)
    if above is not None and not above.is_dir():
        raise ConfigError(f"{flag}={path}: {above} is a file, not a folder")
    existed = path.exists()
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(path, "a"):
            pass
    except OSError as e:
        raise ConfigError(f"{flag}={path}: cannot be written ({e.strerror or e})") from None
    if not existed:
        path.unlink()
