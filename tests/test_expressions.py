"""The expressions of loading programs (hmodel.loading.expressions) are total: reading one either
gives an expression or raises InputError, and evaluating a read one gives a number (±inf or NaN
where the arithmetic fails) or, for a criterion, booleans; never another exception. Random
expression trees are checked against the same arithmetic done directly in NumPy."""

from __future__ import annotations

import operator

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from hmodel.errors import InputError
from hmodel.loading.expressions import MAX_DEPTH, MAX_LENGTH, Criterion, Expression

NAMES = ("p0", "q")
_OPS = {"+": operator.add, "-": operator.sub, "*": operator.mul, "/": operator.truediv}
_COMPARE = {"<": np.less, "<=": np.less_equal, ">": np.greater, ">=": np.greater_equal}


class Node:
    """A generated expression: its text, its value computed directly in NumPy, and whether a
    part of it that uses no name is not finite (the reader refuses it)."""

    def __init__(self, text, value, named, refused):
        self.text, self.value, self.named, self.refused = text, value, named, refused


def _number(text: str, value: float) -> Node:
    return Node(text, lambda env: np.float64(value), False, not np.isfinite(value))


def _compound(text: str, value, children: list[Node]) -> Node:
    named = any(c.named for c in children)
    if named:
        refused = any(c.refused for c in children)
    else:
        with np.errstate(all="ignore"):
            refused = not np.isfinite(value({}))
    return Node(text, value, named, refused)


def _binary(op: str, a: Node, b: Node) -> Node:
    return _compound(f"({a.text} {op} {b.text})", lambda env: _OPS[op](a.value(env), b.value(env)), [a, b])


_leaves = st.one_of(
    st.sampled_from([("0", 0.0), ("1", 1.0), ("0.5", 0.5), ("1e308", 1e308), ("1e-308", 1e-308),
                     ("5e-324", 5e-324), ("1e999", np.inf), ("9" * 400, np.inf), ("150kPa", 150e3),
                     ("2MPa", 2e6), ("1.5e3Pa", 1.5e3)]).map(lambda t: _number(*t)),
    st.floats(min_value=0, allow_infinity=False).map(lambda x: _number(repr(x), x)),
    st.sampled_from(NAMES).map(lambda n: Node(n, lambda env: np.asarray(env[n], np.float64), True, False)))
_trees = st.recursive(_leaves, lambda inner: st.one_of(
    st.tuples(st.sampled_from(sorted(_OPS)), inner, inner).map(lambda t: _binary(*t)),
    inner.map(lambda a: _compound(f"-({a.text})", lambda env: -a.value(env), [a])),
    inner.map(lambda a: _compound(f"abs({a.text})", lambda env: np.abs(a.value(env)), [a]))),
    max_leaves=12)
# values of the names: Python floats (whose division by zero raises) and NumPy arrays
_scalars = st.one_of(st.sampled_from([0.0, -0.0, 1.0, 2e5, 1e308, -1e308, 5e-324, np.inf, -np.inf, np.nan]),
                     st.floats())
_envs = st.one_of(st.fixed_dictionaries({n: _scalars for n in NAMES}),
                  st.fixed_dictionaries({n: st.lists(_scalars, min_size=3, max_size=3).map(np.array)
                                         for n in NAMES}))


def _read(node: Node, read):
    """``read(node.text)``, or None where it is refused as it must be."""
    try:
        return read(node.text)
    except InputError as e:
        assert (node.refused or len(node.text) > MAX_LENGTH or "nested too deeply" in str(e)), (node.text, e)
        return None


@settings(max_examples=300, deadline=None)
@given(tree=_trees, env=_envs)
def test_an_expression_is_read_or_refused_and_its_value_is_numpys(tree, env):
    expression = _read(tree, lambda text: Expression.parse(text, NAMES))
    if expression is None:
        return
    assert not tree.refused
    got = expression(env)
    assert isinstance(got, (np.floating, np.ndarray)) and np.asarray(got).dtype == np.float64
    with np.errstate(all="ignore"):
        want = np.broadcast_to(tree.value(env), np.shape(got))
    np.testing.assert_array_equal(got, want)  # NaN where NumPy gives NaN
    if not np.all(np.isfinite(got)):
        assert expression.fault(env)  # says why, without an exception


@settings(max_examples=200, deadline=None)
@given(left=_trees, op=st.sampled_from(sorted(_COMPARE)), right=_trees, env=_envs)
def test_a_criterion_is_booleans_and_nan_is_not_met(left, op, right, env):
    node = Node(f"q + 0 * ({left.text}) {op} {right.text}", None, True, left.refused or right.refused)
    criterion = _read(node, lambda text: Criterion.parse(text, ("q",), ("p0",)))
    if criterion is None:
        return
    got = criterion(env)
    assert isinstance(got, np.ndarray) and got.dtype == bool
    with np.errstate(all="ignore"):
        want = _COMPARE[op](np.asarray(env["q"], np.float64) + 0 * left.value(env), right.value(env))
    np.testing.assert_array_equal(got, np.broadcast_to(want, got.shape))


_TOKENS = ["p0", "q", "0", "1", "0.5", "1e308", "1e999", "9" * 30, "150kPa", "kPa", "+", "-", "*", "/", "**",
           "%", "//", "(", ")", "abs(", "abs", ",", "<", ">=", "==", "and", "not", "if", "else", "lambda", ":",
           "[", "]", ".", "'", '"', "\\", "\x00", "__import__", "x", "True", "nan", "inf", "\n", " "]


@settings(max_examples=300, deadline=None)
@given(tokens=st.lists(st.sampled_from(_TOKENS), min_size=1, max_size=12) | st.lists(st.text(max_size=6), max_size=3),
       env=_envs)
def test_any_text_is_read_or_refused_in_one_error(tokens, env):
    text = " ".join(tokens)
    for read in (lambda: Expression.parse(text, NAMES), lambda: Criterion.parse(text, ("q",), ("p0",))):
        try:
            value = read()
        except InputError:
            continue
        got = value(env)
        assert np.asarray(got).dtype in (np.float64, bool)


@pytest.mark.parametrize("text, env, want", [
    ("2 * 150kPa", {}, 300000.0),
    ("p0 / (p0 - p0)", {"p0": 2e5}, np.inf),
    ("-p0 / (p0 - p0)", {"p0": 2e5}, -np.inf),
    ("(p0 - p0) / (p0 - p0)", {"p0": 2e5}, np.nan),
    ("p0 * 1e308", {"p0": 2e5}, np.inf),
    ("abs(p0 - 1e308 * p0 * 10)", {"p0": 1.0}, np.inf),
    ("q / p0", {"p0": 0.0, "q": np.array([1.0, 0.0, -1.0])}, np.array([np.inf, np.nan, -np.inf])),
])
def test_known_values(text, env, want):
    names = [n for n in ("p0", "q") if n in text]
    np.testing.assert_array_equal(Expression.parse(text, names)(env), want)


def test_python_floats_divide_by_zero_without_an_exception():
    """A name bound to a Python float (p0 of the iso stage) used to raise ZeroDivisionError."""
    assert np.isnan(Expression.parse("(p0 - p0) / (p0 - p0)", ["p0"])({"p0": 2e5}))
    c = Criterion.parse("q >= p0 / (p0 - p0) - p0 / (p0 - p0)", ["q"], ["p0"])
    assert c({"q": np.array([-1e300, 0.0, 1e300]), "p0": 2e5}).tolist() == [False, False, False]


@pytest.mark.parametrize("text, env, why", [
    ("1e308 * 1e308", {}, "overflow"),
    ("1 / 0", {}, "division by zero"),
    ("2 * (1 / (1 - 1))", {}, "division by zero in 1 / (1 - 1)"),
    ("1 + " + "9" * 400, {}, "too large for floating point in 999"),
    ("p0 / (p0 - p0)", {"p0": 2e5}, "division by zero"),
    ("2 * (p0 * 1e305) * 1e10", {"p0": 2e5}, "overflow in p0 * 1e+305"),
    ("1 + p0", {"p0": float("nan")}, "p0 is not finite"),
])
def test_what_went_wrong_is_said(text, env, why):
    e = Expression.parse(text, list(env)) if env else None
    if e is None:
        with pytest.raises(InputError, match="is not a finite number") as info:
            Expression.parse(text, [])
        assert f"({why}" in str(info.value)
    else:
        assert e.fault(env).startswith(why)


@pytest.mark.parametrize("text", ["abs", "abs + 1", "p0 * abs", "abs(abs)"])
def test_abs_is_only_called(text):
    """A bare ``abs`` used to pass the reader and fail the evaluation with a KeyError."""
    with pytest.raises(InputError, match="abs is a function"):
        Expression.parse(text, ["p0"])


def test_limits_are_refused_when_read():
    with pytest.raises(InputError, match="nested too deeply"):
        Expression.parse("-" * (MAX_DEPTH + 1) + "1", [])
    with pytest.raises(InputError, match=f"at most {MAX_LENGTH}"):
        Expression.parse("1" + " + 1" * MAX_LENGTH, [])
