"""The options contract of restoration methods: what each method declares, and strict checking of what it gets.

A method declares its options once, in its :class:`murk.enhance.declare.Method` (names, types, defaults, ranges,
help); a factory registered with the decorator form of :func:`murk.enhance.restorer.register` declares them as
keyword-only parameters with an annotation and a default, read once by :func:`declared_options`. Such a factory
may not take ``**kwargs``: an option nobody declares is an error naming it, the nearest declared name and the valid
ones, never silently ignored.

Two kinds of options reach :func:`murk.enhance.restorer.create`:

- method options (keyword arguments, or ``?KEY=VALUE,...`` after a spec such as ``post?lam=0.9``): each must be
  declared by at least one stage of the chain, and goes to the stages that declare it;
- shared settings (the ``shared`` mapping: a command's device, batch size, ... at their defaults): each stage
  takes the ones it declares; a name no registered method declares at all is still an error.
"""

from __future__ import annotations

import inspect
import numbers
import os
import types
import typing
from collections.abc import Callable, Iterable, Mapping, Sequence
from typing import Any

from murk._suggest import did_you_mean
from murk.enhance.declare import Option


def declared_options(factory: Callable[..., Any]) -> dict[str, Option]:
    """The options ``factory`` declares, by name (its keyword-only parameters with defaults).

    Raises:
        TypeError: the factory takes ``**kwargs`` (which would swallow misspelt options), positional parameters,
            or an option without a default.
    """
    what = getattr(factory, "__qualname__", repr(factory))
    hints = _type_hints(factory)
    out: dict[str, Option] = {}
    for p in inspect.signature(factory).parameters.values():
        if p.kind is inspect.Parameter.VAR_KEYWORD:
            raise TypeError(
                f"{what}: a restorer factory declares its options as keyword-only parameters; **{p.name} would "
                "swallow misspelt options"
            )
        if p.kind is not inspect.Parameter.KEYWORD_ONLY or p.default is inspect.Parameter.empty:
            raise TypeError(f"{what}: option {p.name!r} must be keyword-only with a default")
        text = p.annotation if isinstance(p.annotation, str) else getattr(p.annotation, "__name__", "Any")
        text = "Any" if p.annotation is inspect.Parameter.empty else text
        out[p.name] = Option(p.name, text, p.default, hints.get(p.name, Any))
    return out


def _type_hints(factory: Callable[..., Any]) -> dict[str, Any]:
    """The factory's annotations, evaluated. One that cannot be evaluated here is left out (its values are not
    type-checked), the others are kept: e.g. ``device: str | torch.device`` in a factory whose module imports
    torch only for type checkers."""
    try:
        return typing.get_type_hints(factory)
    except (NameError, TypeError):
        pass
    globalns = getattr(factory, "__globals__", {})
    hints: dict[str, Any] = {}
    for name, annotation in getattr(factory, "__annotations__", {}).items():
        one = types.SimpleNamespace(__annotations__={name: annotation})
        try:
            hints.update(typing.get_type_hints(one, globalns=globalns))
        except (NameError, TypeError):
            continue
    return hints


def check_value(method: str, option: Option, value: Any) -> None:
    """Raises ValueError unless ``value`` fits the option's declared type (bool, int, float, str, paths, None,
    ``Literal``, tuples and unions of them are checked; other annotations accept anything) and, for a number, its
    declared range (``low``/``high``).

    A spec's options arrive as text (``post?lam=abc``), so a value of the wrong type is a bad value here.
    """
    if not _fits(option.annotation, value):
        raise ValueError(f"method {method}: option {option.name}: expected {_expected(option)}, got {value!r}")
    if isinstance(value, numbers.Real) and not isinstance(value, bool) and not _within(option, float(value)):
        low = "-inf" if option.low is None else float(option.low)
        high = "inf" if option.high is None else float(option.high)
        raise ValueError(
            f"method {method}: option {option.name}: expected a number in [{low}, {high}], got {float(value)}"
        )


def _within(option: Option, value: float) -> bool:
    """Whether ``value`` lies in the option's declared range (NaN never does when a range is declared)."""
    if option.low is None and option.high is None:
        return True
    return (option.low is None or value >= option.low) and (option.high is None or value <= option.high)


def _expected(option: Option) -> str:
    """What an option takes: a Literal's values (also when it may be None, the default that means "not given",
    e.g. a preset's value), else the annotation's text."""
    tp = option.annotation
    parts = list(typing.get_args(tp)) if typing.get_origin(tp) in (typing.Union, types.UnionType) else [tp]
    parts = [p for p in parts if p is not type(None)]
    if len(parts) == 1 and typing.get_origin(parts[0]) is typing.Literal:
        return f"one of {', '.join(map(repr, typing.get_args(parts[0])))}"
    return option.type


def _fits(tp: Any, value: Any) -> bool:
    origin = typing.get_origin(tp)
    if tp is Any or tp is object:
        return True
    if tp is None or tp is type(None):
        return value is None
    if origin is typing.Literal:
        return value in typing.get_args(tp)
    if origin in (typing.Union, types.UnionType):
        return any(_fits(a, value) for a in typing.get_args(tp))
    if origin is tuple:
        return isinstance(value, (tuple, list))
    if tp is bool:
        return isinstance(value, bool)
    if tp is int:
        return isinstance(value, numbers.Integral) and not isinstance(value, bool)
    if tp is float:
        return isinstance(value, numbers.Real) and not isinstance(value, bool)
    if tp is str:
        return isinstance(value, str)
    if isinstance(tp, type) and issubclass(tp, os.PathLike):
        return isinstance(value, (str, os.PathLike))
    return True  # other types (torch.device, classes): the factory checks them


def unknown_option_error(method: str, name: str, valid: Iterable[str]) -> ValueError:
    """The error of an option ``method`` does not declare: names it, the nearest valid one and all valid ones."""
    names = sorted(valid)
    listed = ", ".join(names) if names else "none"
    return ValueError(
        f"method {method}: unknown option {name!r}{did_you_mean(name, names)}; options of {method}: {listed}"
    )


def check_given(
    method: str,
    stages: Sequence[Mapping[str, Option]],
    given: Mapping[str, str],
    registry: Mapping[str, Mapping[str, Option]],
) -> None:
    """Refuse settings the user set explicitly (``given``: option name -> how the user wrote it) that no stage
    of ``method`` declares, naming the methods that take them.

    Raises:
        ValueError: e.g. ``--lambda is an option of post, not of the method 'jointid' (its options: ...)``.
    """
    declared = set().union(*(set(s) for s in stages)) if stages else set()
    for name, label in given.items():
        if name in declared:
            continue
        owners = sorted(m for m, opts in registry.items() if name in opts)
        where = f"an option of {', '.join(owners)}" if owners else "an option of no method"
        raise ValueError(
            f"{label} is {where}, not of the method {method!r} (its options: {', '.join(sorted(declared))}); "
            "leave it out, or use a method that takes it"
            + (f" (e.g. '{method}+post')" if "post" in owners and "post" not in method.split("+") else "")
        )


def route_options(
    method: str,
    stages: Sequence[Mapping[str, Option]],
    options: Mapping[str, Any],
    shared: Mapping[str, Any],
    known: Iterable[str],
) -> list[dict[str, Any]]:
    """The keyword arguments of each stage of ``method``: the declared subset of ``shared`` updated with
    ``options``.

    Args:
        method: the spec, for messages (``"jointid+post"``).
        stages: each stage's declared options.
        options: method options; each must be declared by some stage.
        shared: shared settings; each must be declared by some registered method (``known``).
        known: every option name any registered method declares.

    Raises:
        ValueError: an option no stage declares, or a shared setting no method declares (named, with the
            nearest valid name and the valid ones); an option whose value does not fit its declared type.
    """
    declared = set().union(*(set(s) for s in stages)) if stages else set()
    for name, value in options.items():
        if name not in declared:
            raise unknown_option_error(method, name, declared)
        for stage in stages:
            if name in stage:
                check_value(method, stage[name], value)
    known = sorted(set(known))
    for name in shared:
        if name not in known:
            raise ValueError(
                f"shared setting {name!r}{did_you_mean(name, known)} is an option of no registered method; "
                f"options of the methods: {', '.join(known)}"
            )
    merged = {**shared, **options}
    return [{k: v for k, v in merged.items() if k in stage} for stage in stages]


def parse_spec(spec: str) -> tuple[str, dict[str, Any]]:
    """Split ``METHOD[?KEY=VALUE,...]`` into the method (``"jointid+post"``) and its options.

    Values become int, float or bool (``true``/``false``) when they read as one, else stay strings. Options
    cannot set ``trust_checkpoint`` (specs end up in scripts and configs; trust is an explicit flag).

    Raises:
        ValueError: an option that is not ``KEY=VALUE``, a repeated key, or ``trust_checkpoint``.
    """
    method, _, text = spec.partition("?")
    options: dict[str, Any] = {}
    for item in text.split(","):
        if not item.strip():
            continue
        key, sep, value = item.partition("=")
        key = key.strip()
        if not sep or not key:
            raise ValueError(f"--method {spec}: expected KEY=VALUE options after '?', got {item!r}")
        if key in options:
            raise ValueError(f"--method {spec}: option {key!r} given twice; give it once")
        options[key] = _value(value.strip())
    if "trust_checkpoint" in options:
        raise ValueError(
            f"--method {spec}: trust_checkpoint cannot be set inside a method spec (specs end up in scripts and "
            "configs); pass --trust-checkpoint on the command line or trust_checkpoint=True in the API"
        )
    return method.strip(), options


def _value(text: str) -> Any:
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            pass
    if text.lower() in ("true", "false"):
        return text.lower() == "true"
    return text
