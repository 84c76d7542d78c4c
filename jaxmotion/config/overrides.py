"""Typed, frozen experiment configs: checked overrides, JSON round trips, named experiments.

Configs are nested ``@dataclasses.dataclass(frozen=True)`` classes. Nothing here knows a
particular config: every helper walks the dataclass fields and their type annotations.

Supported field types: ``int``, ``float``, ``bool``, ``str``, ``pathlib.Path``, ``Literal[...]``,
``tuple[X, ...]`` and ``tuple[X, Y]`` (nesting allowed), ``list[X]``, ``dict[K, V]``,
``X | None`` and other unions, and nested dataclasses. A mapping can also be stored as a tuple of
``(str, value)`` pairs, which keeps the config hashable; dotted overrides then address its
entries (``weights.upper=0.5``).

Command-line overrides (``key=value``)::

    lr=3e-4                     float
    ppo.epochs=5                nested field
    use_gp=true                 bool: true/false/1/0/yes/no/on/off
    hidden=512,256  hidden=(512,256)  hidden=[512,256]   tuple
    seed=none                   X | None: none/null
    weights.upper=0.25          entry of a tuple-of-pairs or dict mapping
    weights={"upper": 0.5, "lower": 0.5}                 whole mapping, as JSON

Experiments are files ``experiments/<name>.py`` defining ``config() -> <frozen dataclass>``; a
name may contain ``/`` and ``+`` (``composite/chest_open+squat``). An experiment may build on
another with ``load_experiment("composite/base")`` and ``dataclasses.replace``.
"""

from __future__ import annotations

import ast
import dataclasses
import difflib
import json
import pathlib
import types
import typing
from collections.abc import Mapping, Sequence
from typing import Any

from jaxmotion.config.checks import show, validate
from jaxmotion.config.errors import ConfigError

_NONE_WORDS = ("none", "null")
_TRUE_WORDS = ("true", "1", "yes", "on")
_FALSE_WORDS = ("false", "0", "no", "off")


class _ParseError(Exception):
    """Internal: a value does not parse as a type; turned into a ConfigError with the key."""


# --------------------------------------------------------------------------- type introspection


def _field_types(cls: type) -> dict[str, Any]:
    """Resolved type annotations of the init fields of a dataclass.

    Args:
        cls: a dataclass type.

    Returns:
        Field name -> annotation, for fields with ``init=True``, in declaration order.
    """
    try:
        hints = typing.get_type_hints(cls)
    except Exception as err:  # pylint: disable=broad-except
        raise ConfigError(f"cannot resolve the type annotations of {cls.__qualname__}: {err}") from err
    return {f.name: hints.get(f.name, Any) for f in dataclasses.fields(cls) if f.init}


def _is_dataclass_type(tp: Any) -> bool:
    return isinstance(tp, type) and dataclasses.is_dataclass(tp)


def _is_union(tp: Any) -> bool:
    return typing.get_origin(tp) in (typing.Union, types.UnionType)


def _type_name(tp: Any) -> str:
    """A readable name of an annotation, e.g. ``tuple[int, ...]`` or ``float | None``."""
    if tp is type(None):
        return "None"
    if _is_union(tp):
        return " | ".join(_type_name(a) for a in typing.get_args(tp))
    origin = typing.get_origin(tp)
    if origin is typing.Literal:
        return "Literal[" + ", ".join(repr(a) for a in typing.get_args(tp)) + "]"
    if origin is not None:
        args = typing.get_args(tp)
        inner = ", ".join("..." if a is Ellipsis else _type_name(a) for a in args)
        return f"{getattr(origin, '__name__', str(origin))}[{inner}]"
    if isinstance(tp, type):
        return tp.__name__
    return str(tp).replace("typing.", "")


def _mapping_types(tp: Any) -> tuple[Any, Any, bool] | None:
    """Key and value types of a mapping-like annotation.

    Args:
        tp: an annotation.

    Returns:
        ``(key_type, value_type, is_dict)`` for ``dict[K, V]`` and ``tuple[tuple[K, V], ...]``,
        else None. Optional wrappers are looked through.
    """
    tp = _strip_optional(tp)
    origin = typing.get_origin(tp)
    args = typing.get_args(tp)
    if origin in (dict, Mapping) and len(args) == 2:
        return args[0], args[1], True
    if origin is tuple and len(args) == 2 and args[1] is Ellipsis:
        pair = args[0]
        pair_args = typing.get_args(pair)
        if typing.get_origin(pair) is tuple and len(pair_args) == 2 and Ellipsis not in pair_args:
            return pair_args[0], pair_args[1], False
    return None


def _strip_optional(tp: Any) -> Any:
    """``X | None`` -> ``X``; anything else unchanged."""
    if _is_union(tp):
        args = [a for a in typing.get_args(tp) if a is not type(None)]
        if len(args) == 1:
            return args[0]
    return tp


# --------------------------------------------------------------------------- value coercion


def _split_top_level(text: str) -> list[str]:
    """Splits on commas that are not inside brackets or quotes."""
    parts, depth, quote, start = [], 0, "", 0
    for i, ch in enumerate(text):
        if quote:
            quote = "" if ch == quote else quote
        elif ch in "\"'":
            quote = ch
        elif ch in "([{":
            depth += 1
        elif ch in ")]}":
            depth -= 1
        elif ch == "," and depth == 0:
            parts.append(text[start:i])
            start = i + 1
    parts.append(text[start:])
    return [p.strip() for p in parts]


def _parse_literal(text: str) -> Any:
    """JSON, then a Python literal; raises _ParseError if neither parses."""
    try:
        return json.loads(text)
    except ValueError:
        pass
    try:
        return ast.literal_eval(text)
    except (ValueError, SyntaxError, TypeError, MemoryError, RecursionError) as err:
        raise _ParseError(str(err)) from err


def _parse_sequence(text: str) -> list[Any]:
    """``1,2,3``, ``(1,2,3)``, ``[1, 2, 3]``, ``a,b`` or ``()`` -> a list of items.

    Items come back as strings where the text was not a JSON/Python literal, and are converted
    to the element type by the caller.
    """
    text = text.strip()
    if text[:1] in "([{":
        try:
            value = _parse_literal(text)
        except _ParseError:
            value = None
        if isinstance(value, (list, tuple)):
            return list(value)
        if isinstance(value, dict):
            return list(value.items())
        if text[:1] in "([" and text[-1:] in ")]":
            text = text[1:-1].strip()  # Unquoted strings such as (upper,lower).
    if not text:
        return []
    return _split_top_level(text)


def _unquote(text: str) -> str:
    if len(text) >= 2 and text[0] == text[-1] and text[0] in "\"'":
        return text[1:-1]
    return text


def _coerce(value: Any, tp: Any, cli: bool) -> Any:
    """Converts ``value`` to annotation ``tp``.

    Args:
        value: a command-line string (``cli=True``) or a decoded JSON value (``cli=False``).
        tp: the field's annotation.
        cli: whether ``value`` is raw command-line text, parsed leniently.

    Returns:
        The value as the type expects (tuples for tuples, dataclass instances for dataclasses).

    Raises:
        _ParseError: the value does not fit the type.
    """
    if tp is Any or tp is object:
        return value
    if tp is type(None):
        if value is None or (isinstance(value, str) and value.strip().lower() in _NONE_WORDS):
            return None
        raise _ParseError("expected None")
    if _is_union(tp):
        return _coerce_union(value, typing.get_args(tp), cli)
    origin = typing.get_origin(tp)
    if origin is typing.Literal:
        return _coerce_literal(value, typing.get_args(tp), cli)
    if origin is not None:
        return _coerce_generic(value, origin, typing.get_args(tp), cli)
    if _is_dataclass_type(tp):
        return _coerce_dataclass(value, tp, cli)
    scalar = _SCALARS.get(tp)
    if scalar is not None:
        return scalar(value, cli)
    if isinstance(tp, type) and isinstance(value, tp):
        return value
    raise _ParseError(f"unsupported field type {_type_name(tp)}")


def _coerce_union(value: Any, args: tuple[Any, ...], cli: bool) -> Any:
    if type(None) in args and (value is None or (isinstance(value, str) and value.strip().lower() in _NONE_WORDS)):
        return None
    for arg in args:
        if arg is type(None):
            continue
        try:
            return _coerce(value, arg, cli)
        except _ParseError:
            continue
    raise _ParseError("no member of the union accepts it")


def _coerce_literal(value: Any, choices: tuple[Any, ...], cli: bool) -> Any:
    for choice in choices:
        if value == choice and type(value) is type(choice):
            return choice
        if cli and isinstance(value, str) and _unquote(value.strip()) == str(choice):
            return choice
    listed = ", ".join(repr(c) for c in choices)
    close = difflib.get_close_matches(_unquote(str(value).strip()), [str(c) for c in choices], n=1)
    raise _ParseError(f"must be one of {listed}" + (f" (did you mean {close[0]!r}?)" if close else ""))


def _coerce_generic(value: Any, origin: Any, args: tuple[Any, ...], cli: bool) -> Any:
    if origin in (dict, Mapping):
        return _coerce_dict(value, args, cli)
    if origin not in (tuple, list, Sequence):
        raise _ParseError(f"unsupported generic {origin}")
    if cli and isinstance(value, str):
        items = _parse_sequence(value)
    elif isinstance(value, (list, tuple)):
        items = list(value)
    elif isinstance(value, Mapping):
        items = list(value.items())
    else:
        raise _ParseError("expected a sequence")
    mapping = _mapping_types(origin[args]) if origin is tuple and args else None
    if mapping is not None and cli:
        items = [_split_pair(item) for item in items]
    if origin is tuple and args and args[-1] is not Ellipsis:
        if len(items) != len(args):
            raise _ParseError(f"expected {len(args)} items, got {len(items)}")
        out = [_coerce(item, arg, cli) for item, arg in zip(items, args)]
    else:
        elem = args[0] if args else Any
        out = [_coerce(item, elem, cli) for item in items]
    return list(out) if origin is list else tuple(out)


def _split_pair(item: Any) -> Any:
    """``"upper:0.5"`` -> ``("upper", "0.5")`` for tuple-of-pairs mappings on the command line."""
    if isinstance(item, str) and ":" in item and item[:1] not in "([{":
        key, val = item.split(":", 1)
        return (key.strip(), val.strip())
    return item


def _coerce_dict(value: Any, args: tuple[Any, ...], cli: bool) -> dict[Any, Any]:
    key_tp, val_tp = args if len(args) == 2 else (Any, Any)
    if cli and isinstance(value, str):
        text = value.strip()
        value = _parse_literal(text) if text[:1] == "{" else dict(_split_pair(item) for item in _parse_sequence(text))
    if isinstance(value, (list, tuple)):
        value = dict(value)
    if not isinstance(value, Mapping):
        raise _ParseError("expected a mapping")
    # JSON keys are strings; the annotation decides what they become.
    return {_coerce(k, key_tp, cli or isinstance(k, str)): _coerce(v, val_tp, cli) for k, v in value.items()}


def _coerce_dataclass(value: Any, cls: type, cli: bool) -> Any:
    if isinstance(value, cls):
        return value
    if cli and isinstance(value, str):
        value = _parse_literal(value)
    if not isinstance(value, Mapping):
        raise _ParseError(f"expected a mapping of {cls.__name__} fields")
    try:
        return _from_mapping(cls, value, "", cli)
    except ConfigError as err:
        raise _ParseError(str(err)) from err


def _coerce_bool(value: Any, cli: bool) -> bool:
    if isinstance(value, bool):
        return value
    if isinstance(value, int) and value in (0, 1):
        return bool(value)
    if isinstance(value, str) and cli:
        word = value.strip().lower()
        if word in _TRUE_WORDS:
            return True
        if word in _FALSE_WORDS:
            return False
    raise _ParseError("expected true/false/1/0")


def _coerce_int(value: Any, cli: bool) -> int:
    if isinstance(value, bool):
        raise _ParseError("expected an int, got a bool")
    if isinstance(value, int):
        return value
    if isinstance(value, float) and value.is_integer():
        return int(value)
    if isinstance(value, str) and cli:
        text = value.strip()
        try:
            return int(text)
        except ValueError:
            pass
        try:
            number = float(text)  # 1e6, 2.0
        except ValueError as err:
            raise _ParseError("expected an int") from err
        if number.is_integer():
            return int(number)
    raise _ParseError("expected an int")


def _coerce_float(value: Any, cli: bool) -> float:
    if isinstance(value, bool):
        raise _ParseError("expected a float, got a bool")
    if isinstance(value, (int, float)):
        return float(value)
    if isinstance(value, str) and cli:
        try:
            return float(value.strip())
        except ValueError as err:
            raise _ParseError("expected a float") from err
    raise _ParseError("expected a float")


def _coerce_str(value: Any, cli: bool) -> str:
    if isinstance(value, str):
        return _unquote(value.strip()) if cli else value
    raise _ParseError("expected a string")


def _coerce_path(value: Any, cli: bool) -> pathlib.Path:
    if isinstance(value, pathlib.PurePath):
        return pathlib.Path(value)
    return pathlib.Path(_coerce_str(value, cli))


_SCALARS = {
    bool: _coerce_bool,
    int: _coerce_int,
    float: _coerce_float,
    str: _coerce_str,
    pathlib.Path: _coerce_path,
}


# --------------------------------------------------------------------------- errors


def _joined(prefix: str, name: str) -> str:
    return f"{prefix}.{name}" if prefix else name


def _unknown_key_error(
    name: str, valid: Sequence[str], prefix: str, what: str = "key", whats: str = "keys"
) -> ConfigError:
    full = _joined(prefix, name)
    close = difflib.get_close_matches(name, list(valid), n=1)
    hint = f" (did you mean {_joined(prefix, close[0])!r}?)" if close else ""
    where = f"under {prefix!r}" if prefix else "at the top level"
    return ConfigError(f"unknown config {what} {full!r}{hint}. Valid {whats} {where}: {', '.join(valid)}")


def _bad_value_error(key: str, value: Any, tp: Any, reason: str) -> ConfigError:
    """``key=value: what is wrong`` (a choice among a Literal's: the choices and the closest)."""
    text = value if isinstance(value, str) else show(value)
    if typing.get_origin(_strip_optional(tp)) is typing.Literal:
        return ConfigError(f"{key}={text}: {reason}")
    return ConfigError(f"{key}={text}: {value!r} is not a valid {_type_name(tp)} ({reason})")


# --------------------------------------------------------------------------- to_dict / from_dict


def to_dict(cfg: Any) -> Any:
    """Converts a config to JSON-able Python values.

    Args:
        cfg: a dataclass instance (or any value nested in one).

    Returns:
        Dataclasses become dicts of their init fields, tuples become lists, paths become
        strings; ``from_dict(type(cfg), to_dict(cfg)) == cfg``.
    """
    if dataclasses.is_dataclass(cfg) and not isinstance(cfg, type):
        return {f.name: to_dict(getattr(cfg, f.name)) for f in dataclasses.fields(cfg) if f.init}
    if isinstance(cfg, (list, tuple)):
        return [to_dict(v) for v in cfg]
    if isinstance(cfg, Mapping):
        return {_json_key(k): to_dict(v) for k, v in cfg.items()}
    if isinstance(cfg, pathlib.PurePath):
        return str(cfg)
    if hasattr(cfg, "item") and callable(cfg.item) and getattr(cfg, "ndim", None) == 0:
        return cfg.item()  # numpy / jax scalar
    return cfg


def _json_key(key: Any) -> Any:
    return key if isinstance(key, (str, int, float, bool)) or key is None else str(key)


def from_dict(cls: type, d: Mapping[str, Any]) -> Any:
    """Rebuilds a config from ``to_dict`` output, checking every key and value.

    Args:
        cls: the config's dataclass type.
        d: field name -> JSON value. Fields left out take their defaults.

    Returns:
        An instance of ``cls`` with nested dataclasses and tuples restored from the annotations.

    Raises:
        ConfigError: an unknown key (the message lists the valid ones), a missing required
            field, a value that does not fit its field's type, or one outside its declared
            range or rules (``checks.validate``).
    """
    if not _is_dataclass_type(cls):
        raise ConfigError(f"{cls!r} is not a dataclass type")
    return validate(_from_mapping(cls, d, "", cli=False))


def _from_mapping(cls: type, d: Mapping[str, Any], prefix: str, cli: bool) -> Any:
    if not isinstance(d, Mapping):
        raise ConfigError(f"expected a mapping for {prefix or cls.__name__!r}, got {d!r}")
    types_ = _field_types(cls)
    kwargs = {}
    for name, value in d.items():
        if name not in types_:
            raise _unknown_key_error(str(name), list(types_), prefix)
        key = _joined(prefix, name)
        tp = types_[name]
        if _is_dataclass_type(_strip_optional(tp)) and isinstance(value, Mapping):
            kwargs[name] = _from_mapping(_strip_optional(tp), value, key, cli)
            continue
        try:
            kwargs[name] = _coerce(value, tp, cli)
        except _ParseError as err:
            raise _bad_value_error(key, value, tp, str(err)) from err
    try:
        return cls(**kwargs)
    except TypeError as err:
        raise ConfigError(f"cannot build {cls.__name__} at {prefix or '<root>'!r}: {err}") from err


# --------------------------------------------------------------------------- overrides


def apply_overrides(cfg: Any, overrides: Sequence[str]) -> Any:
    """Returns a copy of ``cfg`` with ``key=value`` overrides applied in order.

    Args:
        cfg: a frozen dataclass instance; never mutated.
        overrides: strings ``key=value`` or ``a.b.c=value``; values are parsed by the field's
            annotation (see the module docstring). A later override of the same key wins.

    Returns:
        A new config built with ``dataclasses.replace``.

    Raises:
        ConfigError: a malformed override, an unknown key (the message lists the valid keys at
            that level and the closest match), a value that does not parse as its type, or a
            result outside the declared ranges and rules (``checks.validate``, run once at the end).
    """
    if isinstance(overrides, str):
        raise ConfigError("overrides must be a list of 'key=value' strings, not one string")
    for item in overrides:
        key, sep, raw = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ConfigError(f"override {item!r} is not of the form key=value")
        cfg = _set_path(cfg, key.split("."), raw, "")
    return validate(cfg)


def _set_path(node: Any, path: list[str], raw: str, prefix: str) -> Any:
    """Replaces the value at ``path`` under dataclass ``node`` by ``raw`` parsed by its type."""
    name, rest = path[0], path[1:]
    if not (dataclasses.is_dataclass(node) and not isinstance(node, type)):
        raise ConfigError(
            f"cannot set {_joined(prefix, '.'.join(path))!r}: {prefix!r} is a "
            f"{type(node).__name__}, not a config section"
        )
    types_ = _field_types(type(node))
    if name not in types_:
        raise _unknown_key_error(name, list(types_), prefix)
    key, tp = _joined(prefix, name), types_[name]
    if not rest:
        try:
            value = _coerce(raw, tp, cli=True)
        except _ParseError as err:
            raise _bad_value_error(key, raw, tp, str(err)) from err
        return dataclasses.replace(node, **{name: value})
    child = getattr(node, name)
    if _mapping_types(tp) is not None and child is not None:
        value = _set_mapping_entry(child, tp, rest, raw, key)
    else:
        if child is None and _is_dataclass_type(_strip_optional(tp)):
            child = _default_instance(_strip_optional(tp), key)
        value = _set_path(child, rest, raw, key)
    return dataclasses.replace(node, **{name: value})


def _default_instance(cls: type, key: str) -> Any:
    """A section that is None gets its defaults before a dotted override fills it in."""
    try:
        return cls()
    except TypeError as err:
        raise ConfigError(
            f"{key!r} is None and {cls.__name__} has required fields; set it whole with {key}='{{...}}' (JSON)"
        ) from err


def _set_mapping_entry(mapping: Any, tp: Any, rest: list[str], raw: str, key: str) -> Any:
    """Sets one existing entry of a dict or tuple-of-pairs field from ``key.entry=value``."""
    _, val_tp, is_dict = _mapping_types(tp)
    items = list(mapping.items()) if is_dict else [tuple(p) for p in mapping]
    entry = ".".join(rest)
    names = [str(k) for k, _ in items]
    if entry not in names:
        raise _unknown_key_error(entry, names, key, what="entry", whats="entries")
    full = _joined(key, entry)
    try:
        value = _coerce(raw, val_tp, cli=True)
    except _ParseError as err:
        raise _bad_value_error(full, raw, val_tp, str(err)) from err
    items = [(k, value if str(k) == entry else v) for k, v in items]
    return dict(items) if is_dict else tuple(items)
