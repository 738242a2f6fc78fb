"""How a restoration method is declared: one :class:`Method` per method (its name, its options with types, ranges,
defaults and one line of help each, what it needs, and the import path of its implementation), read by the
registry (:mod:`murk.enhance.restorer`), ``murk enhance --help``, ``murk live``'s method menu, the options table of
docs/enhance.md and the spec checker (:mod:`murk.enhance.options`). Importing it imports nothing beyond the
standard library and :mod:`murk.enhance.choices`, so every name and option is known before torch, OpenCV or a
network is loaded; the built-in declarations are :data:`murk.enhance.methods.BUILTIN`.

The implementation is called with the options checked and completed (every declared option, its default where
not given) as one :class:`Checked` mapping, read as attributes: ``def create_mine(o: Checked) -> Restorer:
return Mine(o.strength)``. Adding a method is one declaration plus one implementation (docs/DESIGN.md).

A :class:`Preset` is a method declared as a spec of other methods (:mod:`murk.enhance.spec`: chains ``a+b``, blends
``a|b@w``): ``jointid`` is ``jointid_net|lite@lite_blend``. It needs no implementation of its own.
"""

from __future__ import annotations

import importlib
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

from murk.enhance import choices
from murk.enhance.spec import names, parse_method, weight_names

Need = Literal["torch", "weights", "onnxruntime"]
"""What a method needs: torch; a weights file (``weights``: shipped with murk or given); ONNX Runtime (only for an
``.onnx`` file)."""
NEEDS: tuple[Need, ...] = ("torch", "weights", "onnxruntime")

_NAMESPACE: dict[str, Any] = {"Path": Path, "Any": Any, "Literal": Literal, **vars(choices)}
"""What an option's type text may name (``str | Path | None``, ``Precision``, ...)."""


def _annotation(text: str) -> Any:
    """The type that ``text`` names, or ``Any`` when it names something not importable here (``torch.device``:
    the implementation checks such values)."""
    try:
        return eval(text, dict(_NAMESPACE))  # declared type texts, never user input
    except (NameError, AttributeError, TypeError, SyntaxError):
        return Any


@dataclass(frozen=True)
class Option:
    """One declared option of a method.

    Attributes:
        name: the keyword (``lam``; in a spec ``post?lam=0.5``).
        type: the type as text (``float | None``, ``Precision``), shown in messages, help and the live page.
        default: the value when not given.
        annotation: the type itself (``Any`` when it cannot be resolved without torch): what the checker checks.
        help: one line on what it does.
        low, high: the inclusive range of a number (None: unbounded), checked with the type.
    """

    name: str
    type: str
    default: Any
    annotation: Any = Any
    help: str = ""
    low: float | None = None
    high: float | None = None

    def __str__(self) -> str:
        return f"{self.name}: {self.type} = {self.default!r}"


def opt(
    name: str, type: str, default: Any, help: str, *, low: float | None = None, high: float | None = None
) -> Option:
    """An :class:`Option` whose annotation is resolved from its type text."""
    return Option(name, type, default, _annotation(type), help, low, high)


class Checked(Mapping[str, Any]):
    """The options an implementation gets: every declared option, checked, its default where not given; read as
    attributes (``o.checkpoint``) or as a mapping (``**o``)."""

    def __init__(self, values: Mapping[str, Any]) -> None:
        self._values = dict(values)

    def __getattr__(self, name: str) -> Any:
        try:
            return self.__dict__["_values"][name]
        except KeyError:
            raise AttributeError(name) from None

    def __getitem__(self, name: str) -> Any:
        return self._values[name]

    def __iter__(self) -> Iterator[str]:
        return iter(self._values)

    def __len__(self) -> int:
        return len(self._values)

    def __repr__(self) -> str:
        return f"Checked({self._values!r})"


Implementation = Callable[[Checked], Any]
_RESERVED = "+|@()?,="


def check_name(name: str) -> None:
    """Raise ValueError unless ``name`` can stand in a spec: not empty, no white space, none of ``+|@()?,=``."""
    if not name or name != "".join(name.split()) or any(c in name for c in _RESERVED):
        raise ValueError(f"name: expected a non-empty name without white space or any of {_RESERVED!r}, got {name!r}")


def _load(path: str | Callable[..., Any]) -> Callable[..., Any]:
    if callable(path):
        return path
    module, _, attr = path.partition(":")
    fn: Callable[..., Any] = getattr(importlib.import_module(module), attr)
    return fn


@dataclass(frozen=True)
class Method:
    """The one declaration of a restoration method.

    Attributes:
        name: the name in a spec (``jointid``; none of the grammar's characters, :func:`check_name`).
        implementation: ``"module:function"`` (imported when the method is built) or the function itself; called
            with the :class:`Checked` options, it returns the :class:`~murk.enhance.restorer.Restorer`.
        options: the declared options, in the order help and the live page show them.
        help: one line on what the method does.
        needs: what it needs (:data:`Need`), shown in help and the docs.
        preflight: ``"module:function"`` or a function, called with the checked options by
            ``restorer.check(files=True)`` and before the implementation is imported: it raises what the
            implementation would about the files the options name (a weights file that is not there) without
            reading them or importing torch.
    """

    name: str
    implementation: str | Implementation
    options: tuple[Option, ...] = ()
    help: str = ""
    needs: tuple[Need, ...] = ()
    preflight: str | Callable[..., None] | None = None
    _by_name: dict[str, Option] = field(init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        check_name(self.name)
        for what, path in (("implementation", self.implementation), ("preflight", self.preflight)):
            if isinstance(path, str) and path.count(":") != 1:
                raise ValueError(f"{what}: expected 'module:function', got {path!r}")
        unknown = [n for n in self.needs if n not in NEEDS]
        if unknown:
            raise ValueError(f"needs: expected some of {', '.join(NEEDS)}, got {unknown[0]!r}")
        by_name = {o.name: o for o in self.options}
        if len(by_name) != len(self.options):
            raise ValueError(f"options: {self.name} declares an option twice")
        object.__setattr__(self, "_by_name", by_name)

    @property
    def option_map(self) -> dict[str, Option]:
        """The options by name (a copy)."""
        return dict(self._by_name)

    def checked(self, given: Mapping[str, Any]) -> Checked:
        """``given`` (declared names, values checked by the registry) completed with the defaults."""
        return Checked({o.name: given.get(o.name, o.default) for o in self.options})

    def check_files(self, given: Mapping[str, Any]) -> None:
        """Run the preflight (if any) on the completed options."""
        if self.preflight is not None:
            _load(self.preflight)(**self.checked(given))

    def build(self, given: Mapping[str, Any]) -> Any:
        """The restorer: the preflight, then the implementation (imported now) on the completed options."""
        options = self.checked(given)
        if self.preflight is not None:
            _load(self.preflight)(**options)
        return _load(self.implementation)(options)


@dataclass(frozen=True)
class Preset:
    """A method declared as a spec of other methods (:mod:`murk.enhance.spec`): e.g. ``jointid`` is
    ``jointid_net|lite@lite_blend``, Joint-ID with the shipped ``lite``'s restoration blended in.

    Its options are every option of its first method plus its own, which name the spec's weights
    (``lite_blend``). The first method takes every option given to the preset that it declares; the other methods
    take only those listed in ``passes`` (``device``), and their defaults otherwise. A weight of 0 leaves its member
    out (not built): ``jointid?lite_blend=0`` is ``jointid_net`` itself. What the preset builds is named after it.

    Attributes:
        name: the name in a spec.
        spec: the methods it runs, in the spec grammar, without ``?`` options; a weight may name one of ``options``.
        options: its own options: one for each weight the spec names, with its default, range and help.
        help: one line on what it does.
        passes: the preset's options that the methods after the first take (when they declare them).
    """

    name: str
    spec: str
    options: tuple[Option, ...] = ()
    help: str = ""
    passes: tuple[str, ...] = ()

    def __post_init__(self) -> None:
        check_name(self.name)
        tree = parse_method(self.spec, named_weights=True)
        if self.name in names(tree):
            raise ValueError(f"spec: the preset {self.name} cannot run itself, got {self.spec!r}")
        own, named = {o.name for o in self.options}, set(weight_names(tree))
        if own != named:
            raise ValueError(
                f"options: the options of the preset {self.name} are the weights its spec names "
                f"({', '.join(sorted(named)) or 'none'}), got {', '.join(sorted(own)) or 'none'}"
            )

    @property
    def first(self) -> str:
        """The first method of the spec: the one whose options the preset takes."""
        return names(parse_method(self.spec, named_weights=True))[0]
