"""The method grammar: how a spec names the methods it runs, chained and blended (standard library only).

::

    spec   := expr ['?' KEY=VALUE,...]      options: to every method of the spec that declares them
    expr   := blend ('+' blend)*             a chain: left to right, each on the output of the one before
    blend  := term ('|' term '@' WEIGHT)*    (1 - W) * left + W * right, of the two restorations of the same input
    term   := NAME | '(' expr ')'

``|`` binds tighter than ``+``: ``jointid_net|lite@0.5+post`` is the blend, then ``post`` on it; a blend of a chain
needs parentheses (``(lite+post)|colorbalance@0.3``). Blends of more than two go left to right:
``a|b@0.5|c@0.2`` is ``(a|b@0.5)|c@0.2``. ``WEIGHT`` is a number in [0, 1] (the right member's share); in a preset's
declaration (:class:`murk.enhance.declare.Preset`) it may instead name one of the preset's options
(``jointid_net|lite@lite_blend``). This module parses the part before ``?``
(:func:`murk.enhance.options.parse_spec` splits the options off); :mod:`murk.enhance.restorer` builds the tree.
"""

from __future__ import annotations

import math
import re
from collections.abc import Iterator
from dataclasses import dataclass

SEPARATORS = "+|@()"
"""The characters of the grammar (with ``?``, ``,`` and ``=`` of the options): never part of a method's name."""


@dataclass(frozen=True)
class Term:
    """One method, by name."""

    name: str


@dataclass(frozen=True)
class ChainSpec:
    """Methods run left to right (two or more; nested chains are flattened)."""

    parts: tuple[Node, ...]


@dataclass(frozen=True)
class BlendSpec:
    """``(1 - weight) * left + weight * right``; ``weight`` a number in [0, 1], or the name of a preset's option."""

    left: Node
    right: Node
    weight: float | str


Node = Term | ChainSpec | BlendSpec
BLEND_FORM = "a blend is A|B@W, W in [0, 1] the share of B (e.g. jointid_net|lite@0.5)"

_TOKEN = re.compile(r"\s*([+|@()]|[^+|@()\s][^+|@()]*)")


def parse_method(text: str, *, named_weights: bool = False) -> Node:
    """The tree of ``text`` (a spec without its ``?`` options).

    Args:
        text: e.g. ``"jointid"``, ``"lite+post"``, ``"jointid_net|lite@0.5+post"``.
        named_weights: whether a weight may name an option (a preset's declaration) instead of being a number.

    Raises:
        ValueError: a missing or misplaced name, weight or parenthesis, or a weight that is not a number in
            [0, 1]; the message quotes ``text``, says what was expected where, and shows the blend's form.
    """
    return _Parser(text, named_weights).parse()


def names(node: Node) -> list[str]:
    """The method names of ``node``, left to right (one per :class:`Term`, repeats kept)."""
    return list(_names(node))


def _names(node: Node) -> Iterator[str]:
    if isinstance(node, Term):
        yield node.name
    elif isinstance(node, ChainSpec):
        for part in node.parts:
            yield from _names(part)
    else:
        yield from _names(node.left)
        yield from _names(node.right)


def weight_names(node: Node) -> list[str]:
    """The option names that the weights of ``node`` name (a preset's declaration), left to right."""
    if isinstance(node, Term):
        return []
    if isinstance(node, ChainSpec):
        return [w for part in node.parts for w in weight_names(part)]
    own = [node.weight] if isinstance(node.weight, str) else []
    return weight_names(node.left) + weight_names(node.right) + own


class _Parser:
    def __init__(self, text: str, named_weights: bool) -> None:
        self.text = text
        self.named_weights = named_weights
        self.tokens = [m.group(1).strip() for m in _TOKEN.finditer(text)]
        self.i = 0

    def error(self, message: str) -> ValueError:
        return ValueError(f"method {self.text!r}: {message}")

    def peek(self) -> str | None:
        return self.tokens[self.i] if self.i < len(self.tokens) else None

    def take(self) -> str | None:
        token = self.peek()
        self.i += 1
        return token

    def parse(self) -> Node:
        if not self.tokens:
            raise self.error("expected a method name, got nothing")
        node = self.expr()
        token = self.peek()
        if token is not None:
            after = self.tokens[self.i - 1]
            if token == "@":
                raise self.error(f"'@' after {after!r} weights the second member of a blend; {BLEND_FORM}")
            if token == ")":
                raise self.error(f"')' after {after!r} closes no '('")
            raise self.error(f"expected '+' or '|' after {after!r}, got {token!r}")
        return node

    def expr(self, after: str = "start") -> Node:
        parts = [self.blend(after)]
        while self.peek() == "+":
            self.take()
            parts.append(self.blend("'+'"))
        flat = tuple(p for part in parts for p in (part.parts if isinstance(part, ChainSpec) else (part,)))
        return parts[0] if len(parts) == 1 else ChainSpec(flat)

    def blend(self, after: str) -> Node:
        node = self.term(after)
        while self.peek() == "|":
            self.take()
            right = self.term("'|'")
            if self.peek() != "@":
                raise self.error(f"the blend with {_shown(right)} needs a weight: {BLEND_FORM}")
            self.take()
            node = BlendSpec(node, right, self.weight())
        return node

    def term(self, after: str) -> Node:
        token = self.take()
        if token == "(":
            node = self.expr("'('")
            if self.take() != ")":
                raise self.error("expected ')' to close '(' (options go after '?' at the end of the spec)")
            return node
        if token is None or token in SEPARATORS:
            got = "the end" if token is None else repr(token)
            where = "at the start" if after == "start" else f"after {after}"
            form = f"; {BLEND_FORM}" if after == "'|'" else ""
            raise self.error(f"expected a method name {where}, got {got}{form}")
        return Term(token)

    def weight(self) -> float | str:
        token = self.take()
        if token is None or token in SEPARATORS:
            got = "the end" if token is None else repr(token)
            raise self.error(f"expected a weight in [0, 1] after '@', got {got}; {BLEND_FORM}")
        try:
            value = float(token)
        except ValueError:
            if self.named_weights and token.isidentifier():
                return token
            raise self.error(f"expected a weight in [0, 1] after '@', got {token!r}; {BLEND_FORM}") from None
        if not (math.isfinite(value) and 0.0 <= value <= 1.0):
            raise self.error(f"expected a weight in [0, 1] after '@', got {token}; {BLEND_FORM}")
        return value


def _shown(node: Node) -> str:
    return repr(node.name) if isinstance(node, Term) else "its second member"
