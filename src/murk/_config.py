"""The one config loader: frozen-dataclass configurations to and from plain dicts / YAML, strictly validated.

Every YAML murk reads goes through :func:`read_yaml` (a mapping, or an error naming the file: missing, not
UTF-8, invalid YAML, not a mapping) and every config dataclass is built by :func:`from_dict` (scenes, synth,
train, study; the network configs of Joint-ID, lite and the baselines from checkpoints). Unknown keys (named,
with the valid ones), wrong types and bad ``Literal`` values are errors that name the key path (and the file
when loaded from one). Lists become tuples, so configs stay hashable and immutable.
"""

from __future__ import annotations

import dataclasses
import types
import typing
from pathlib import Path
from typing import Any, TypeVar, get_args, get_origin, get_type_hints

import yaml

from murk._suggest import did_you_mean

T = TypeVar("T")


def to_dict(obj: Any) -> Any:
    """A dataclass tree as plain dicts/lists (YAML/JSON-ready)."""
    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        return {f.name: to_dict(getattr(obj, f.name)) for f in dataclasses.fields(obj)}
    if isinstance(obj, (list, tuple)):
        return [to_dict(v) for v in obj]
    if isinstance(obj, dict):
        return {k: to_dict(v) for k, v in obj.items()}
    return obj


def from_dict(cls: type[T], data: Any, *, where: str = "config") -> T:
    """Build dataclass ``cls`` from ``data`` (missing keys take the defaults)."""
    return _convert(cls, data, where)


def as_config(cls: type[T], config: T | dict[str, Any] | None, *, where: str = "config") -> T | None:
    """``config`` as a ``cls``: a dict is built with :func:`from_dict`, an instance and None (the caller's
    default) are returned as they are.

    Raises:
        TypeError: ``config`` is neither a ``cls``, a dict nor None.
        ValueError: invalid values or unknown keys in a dict.
    """
    if isinstance(config, dict):
        config = from_dict(cls, config, where=where)
    if config is not None and not isinstance(config, cls):
        raise TypeError(f"{where}: expected a {cls.__name__}, a dict or None, got {type(config).__name__}")
    return config


def merge(base: T, overrides: dict[str, Any], *, where: str = "overrides") -> T:
    """A copy of ``base`` with nested ``overrides`` applied (keys validated like :func:`from_dict`)."""
    data = to_dict(base)
    _deep_update(data, overrides)
    return from_dict(type(base), data, where=where)


PROVENANCE_KEYS = ("murk_version", "world_size")
"""Top-level keys murk writes into the config.yaml of every output folder to record the run (not settings):
:func:`load_yaml` ignores them, so an output folder's config.yaml reproduces its run."""


def read_yaml(path: str | Path, *, what: str = "settings") -> dict[str, Any]:
    """The mapping in a YAML file (``yaml.safe_load``; an empty file is ``{}``).

    Raises:
        ValueError: naming the file: not found, not UTF-8, invalid YAML, nested too deeply, or not a mapping
            (of ``what``).
    """
    path = Path(path)
    if not path.is_file():
        raise ValueError(f"{path}: config file not found")
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as exc:
        raise ValueError(f"{path}: cannot read this config file ({(exc.strerror or str(exc)).lower()})") from None
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    try:
        data = yaml.safe_load(text)
    except yaml.YAMLError as exc:
        raise ValueError(f"{path}: invalid YAML ({_yaml_problem(exc)})") from None
    except UnicodeDecodeError as exc:
        raise ValueError(f"{path}: not UTF-8 text ({exc.reason} at byte {exc.start})") from None
    except RecursionError:
        raise ValueError(f"{path}: YAML nested too deeply") from None
    if data is None:
        return {}
    if not isinstance(data, dict):
        raise ValueError(f"{path}: expected a mapping of {what}, got {_short(data)}")
    return data


def _yaml_problem(exc: yaml.YAMLError) -> str:
    """A YAML error on one line: what went wrong and where (line and column counted from 1)."""
    problem = getattr(exc, "problem", None) or str(exc).splitlines()[0]
    mark = getattr(exc, "problem_mark", None)
    where = f" at line {mark.line + 1}, column {mark.column + 1}" if mark is not None else ""
    tag = " (YAML tags such as !!python/... are refused: configs are read with yaml.safe_load)"
    return f"{problem}{where}" + (tag if "constructor" in type(exc).__name__.lower() else "")


def load_yaml(cls: type[T], path: str | Path) -> T:
    """Load a YAML file into ``cls``; errors name the file and the key. The provenance keys written by
    :func:`dump_yaml` (:data:`PROVENANCE_KEYS`) are ignored."""
    data = read_yaml(path, what=f"{getattr(cls, '__name__', cls)} fields")
    data = {k: v for k, v in data.items() if k not in PROVENANCE_KEYS}
    return from_dict(cls, data, where=str(path))


def dump_yaml(obj: Any, **extra: Any) -> str:
    """YAML text of a config (plus ``extra`` top-level keys such as seed and version)."""
    data = dict(extra)
    data.update(to_dict(obj))
    return yaml.safe_dump(data, sort_keys=False)


def _short(value: Any, limit: int = 80) -> str:
    """``repr(value)`` cut to ``limit`` characters: an error message must stay one line even for a huge or deeply
    nested value (a YAML anchor bomb expands to gigabytes of repr)."""
    if isinstance(value, (dict, list, tuple)):
        return f"a {type(value).__name__} of {len(value)} item(s)"
    text = repr(value)
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _deep_update(dst: dict[str, Any], src: dict[str, Any]) -> None:
    for k, v in src.items():
        if isinstance(v, dict) and isinstance(dst.get(k), dict):
            _deep_update(dst[k], v)
        else:
            dst[k] = v


def _convert(tp: Any, value: Any, where: str) -> Any:
    origin = get_origin(tp)
    if dataclasses.is_dataclass(tp):
        if not isinstance(value, dict):
            raise ValueError(f"{where}: expected a mapping, got {type(value).__name__}")
        hints = get_type_hints(tp)
        names = {f.name for f in dataclasses.fields(tp) if f.init}
        unknown = sorted(set(value) - names)
        if unknown:
            hint = did_you_mean(unknown[0], names) if len(unknown) == 1 else ""
            raise ValueError(f"{where}: unknown key(s) {', '.join(unknown)}{hint}; allowed: {', '.join(sorted(names))}")
        kwargs = {k: _convert(hints[k], v, f"{where}.{k}") for k, v in value.items()}
        try:
            return typing.cast(Any, tp)(**kwargs)
        except (TypeError, ValueError) as exc:
            raise ValueError(f"{where}: {exc}") from None
    if tp is Any:
        return value
    if origin is typing.Literal:
        allowed = get_args(tp)
        if value not in allowed:
            raise ValueError(f"{where}: expected one of {', '.join(map(repr, allowed))}, got {_short(value)}")
        return value
    if origin in (typing.Union, types.UnionType):
        args = get_args(tp)
        if value is None and type(None) in args:
            return None
        errors = []
        for arg in args:
            if arg is type(None):
                continue
            try:
                return _convert(arg, value, where)
            except ValueError as exc:
                errors.append(str(exc))
        raise ValueError(errors[0] if len(errors) == 1 else f"{where}: {_short(value)} matches none of {tp}")
    if origin is tuple:
        args = get_args(tp)
        if not isinstance(value, (list, tuple)):
            raise ValueError(f"{where}: expected a list, got {_short(value)}")
        if len(args) == 2 and args[1] is Ellipsis:
            return tuple(_convert(args[0], v, f"{where}[{i}]") for i, v in enumerate(value))
        if len(value) != len(args):
            raise ValueError(f"{where}: expected {len(args)} values, got {len(value)}")
        return tuple(_convert(a, v, f"{where}[{i}]") for i, (a, v) in enumerate(zip(args, value, strict=True)))
    if tp is bool:
        if not isinstance(value, bool):
            raise ValueError(f"{where}: expected true/false, got {_short(value)}")
        return value
    if tp is int:
        if isinstance(value, bool) or not isinstance(value, int):
            raise ValueError(f"{where}: expected an integer, got {_short(value)}")
        return value
    if tp is float:
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise ValueError(f"{where}: expected a number, got {_short(value)}")
        return float(value)
    if tp is str:
        if not isinstance(value, str):
            raise ValueError(f"{where}: expected a string, got {_short(value)}")
        return value
    raise TypeError(f"{where}: unsupported config type {tp!r}")
