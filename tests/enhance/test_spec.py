"""The method grammar (murk.enhance.spec): chains with '+', blends with 'A|B@W' binding tighter, parentheses, and a
clear message for every malformed spec."""

from __future__ import annotations

import pytest

from murk.enhance.spec import BlendSpec, ChainSpec, Term, names, parse_method, weight_names

A, B, C = Term("a"), Term("b"), Term("c")


@pytest.mark.parametrize(
    ("text", "tree"),
    [
        ("a", A),
        (" a + b ", ChainSpec((A, B))),
        ("a|b@0.5", BlendSpec(A, B, 0.5)),
        ("a|b@0.3+c", ChainSpec((BlendSpec(A, B, 0.3), C))),  # '|' binds tighter than '+'
        ("c+a|b@1", ChainSpec((C, BlendSpec(A, B, 1.0)))),
        ("a|b@0.5|c@0.2", BlendSpec(BlendSpec(A, B, 0.5), C, 0.2)),  # left to right
        ("(a+b)|c@0", BlendSpec(ChainSpec((A, B)), C, 0.0)),
        ("a+(b+c)", ChainSpec((A, B, C))),  # nested chains are one chain
        ("a|(b+c)@1e-1", BlendSpec(A, ChainSpec((B, C)), 0.1)),
    ],
)
def test_specs_parse_into_their_trees(text: str, tree: object) -> None:
    assert parse_method(text) == tree


def test_names_and_named_weights_are_listed_left_to_right() -> None:
    tree = parse_method("jointid_net|lite@lite_blend+post", named_weights=True)
    assert names(tree) == ["jointid_net", "lite", "post"] and weight_names(tree) == ["lite_blend"]
    assert names(parse_method("a|a@0.5")) == ["a", "a"]


@pytest.mark.parametrize(
    ("text", "message"),
    [
        ("lite|@2", r"method 'lite\|@2': expected a method name after '\|', got '@'; a blend is A\|B@W"),
        ("lite|post", r"the blend with 'post' needs a weight: a blend is A\|B@W, W in \[0, 1\] the share of B"),
        ("lite|post@2", r"expected a weight in \[0, 1\] after '@', got 2; a blend is A\|B@W"),
        ("lite|post@-0.1", r"expected a weight in \[0, 1\] after '@', got -0.1"),
        ("lite|post@nan", r"expected a weight in \[0, 1\] after '@', got nan"),
        ("lite|post@half", r"expected a weight in \[0, 1\] after '@', got 'half'"),  # names: only in presets
        ("lite|post@", r"expected a weight in \[0, 1\] after '@', got the end"),
        ("lite@0.5", r"'@' after 'lite' weights the second member of a blend"),
        ("lite+", r"expected a method name after '\+', got the end"),
        ("+lite", r"expected a method name at the start, got '\+'"),
        ("(lite", r"expected '\)' to close '\(' \(options go after '\?' at the end of the spec\)"),
        ("lite)", r"'\)' after 'lite' closes no '\('"),
        ("()", r"expected a method name after '\(', got '\)'"),
        ("", r"method '': expected a method name, got nothing"),
    ],
)
def test_malformed_specs_say_what_was_expected_where(text: str, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        parse_method(text)
