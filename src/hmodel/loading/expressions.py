"""Arithmetic and stopping criteria of loading programs, read without ``eval``.

A program's stress targets (``q = "0.25 * p0"``) and stopping criteria
(``until = "p <= 0.05 * p0"``) are tiny expressions over known names. Python's own parser
(:mod:`ast`) reads them into a tree; only numbers, pressures with units (``150kPa``), known
names, ``+ - * /``, unary minus, ``abs(...)`` and, for a criterion, one comparison are
accepted, and the tree is evaluated by walking it: nothing of the text is ever executed.

An expression is at most :data:`MAX_LENGTH` characters and :data:`MAX_DEPTH` levels deep, so
that neither the parser nor the walk can run out of stack. Every part of it that uses no name
(``1/0``, ``2 * 150kPa``) is evaluated when it is read and must be a finite number; the rest is
evaluated in NumPy floating point, names' values included, where a division by zero or an
overflow gives ±inf or NaN rather than an exception: the evaluation of a read expression is total
(a stress target that is not finite is refused where it is used, naming what went wrong
(:meth:`Expression.fault`); a criterion that is NaN is not met).
"""

from __future__ import annotations

import ast
import operator
import re
from collections.abc import Mapping
from dataclasses import dataclass

import numpy as np

from ..errors import InputError

_BINARY = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul,
           ast.Div: operator.truediv}
_COMPARE = {ast.Lt: ("<", np.less), ast.LtE: ("<=", np.less_equal), ast.Gt: (">", np.greater),
            ast.GtE: (">=", np.greater_equal)}
_UNITS = {"Pa": 1.0, "kPa": 1e3, "MPa": 1e6, "GPa": 1e9}
#: Longest expression text [characters].
MAX_LENGTH = 500
#: Deepest nesting of an expression's tree (operators, parentheses, unary minus).
MAX_DEPTH = 40
# "150kPa" -> "(150*kPa)": units become names, bound to their factors when evaluated
_WITH_UNIT = re.compile(r"(\d(?:[\d.]*(?:[eE][-+]?\d+)?)?)\s*(Pa|kPa|MPa|GPa)\b")


def _parse(text: str, what: str) -> ast.AST:
    if not isinstance(text, str) or not text.strip():
        raise InputError(f"{what} must be a non-empty text, got {text!r}")
    if len(text) > MAX_LENGTH:
        raise InputError(f"{what} is {len(text)} characters long; an expression has at most {MAX_LENGTH}")
    try:
        tree = ast.parse(_WITH_UNIT.sub(r"(\1*\2)", text.strip()), mode="eval").body
    except (SyntaxError, ValueError):  # ValueError: a null byte
        raise InputError(f"{what} {text!r} is not an expression of numbers and known names") from None
    except (RecursionError, MemoryError):
        raise InputError(f"{what} is nested too deeply (at most {MAX_DEPTH} levels)") from None
    if _depth(tree) > MAX_DEPTH:
        raise InputError(f"{what} is nested too deeply (at most {MAX_DEPTH} levels)")
    return tree


def _depth(tree: ast.AST) -> int:
    """Levels of ``tree``, counted without recursion."""
    deepest, todo = 0, [(tree, 1)]
    while todo:
        node, d = todo.pop()
        deepest = max(deepest, d)
        todo.extend((child, d + 1) for child in ast.iter_child_nodes(node)
                    if not isinstance(child, (ast.expr_context, ast.operator, ast.unaryop, ast.cmpop)))
    return deepest


def _check_constants(node: ast.AST, used: set[str], what: str, text: str) -> None:
    """Every largest part of ``node`` that uses no name must evaluate to a finite number."""
    if not (used & _free_names(node)):
        if not np.isfinite(_value(node, {})):
            raise InputError(f"{what} {text!r}: {ast.unparse(node)} is not a finite number "
                             f"({_fault(node, {})})")
        return
    for child in ast.iter_child_nodes(node):
        if isinstance(child, ast.expr) and not (isinstance(child, ast.Name) and child.id == "abs"):
            _check_constants(child, used, what, text)


def _free_names(node: ast.AST) -> set[str]:
    return {n.id for n in ast.walk(node) if isinstance(n, ast.Name) and n.id not in _UNITS}


def _names(node: ast.AST, known: set[str], what: str, text: str) -> set[str]:
    """The names ``node`` uses; every node must be of the accepted kinds."""
    used = set()
    called = {id(n.func) for n in ast.walk(node) if isinstance(n, ast.Call)}
    for n in ast.walk(node):
        if isinstance(n, ast.Call):
            if not (isinstance(n.func, ast.Name) and n.func.id == "abs" and len(n.args) == 1
                    and not n.keywords):
                raise InputError(f"{what} {text!r}: only abs(x) may be called")
        elif isinstance(n, ast.Name):
            if n.id == "abs":  # a function, not a value: only where it is called
                if id(n) not in called:
                    raise InputError(f"{what} {text!r}: abs is a function: abs(x)")
                continue
            if n.id not in known and n.id not in _UNITS:
                raise InputError(f"{what} {text!r}: unknown name {n.id!r} (known: "
                                 f"{', '.join(sorted(known))})")
            used.add(n.id)
        elif isinstance(n, ast.Constant):
            if isinstance(n.value, bool) or not isinstance(n.value, (int, float)):
                raise InputError(f"{what} {text!r}: {n.value!r} is not a number")
        elif isinstance(n, ast.BinOp):
            if type(n.op) not in _BINARY:
                raise InputError(f"{what} {text!r}: only + - * / are allowed")
        elif isinstance(n, ast.UnaryOp):
            if not isinstance(n.op, (ast.USub, ast.UAdd)):
                raise InputError(f"{what} {text!r}: only unary minus is allowed")
        elif not isinstance(n, (ast.Load, ast.operator, ast.unaryop, ast.cmpop, ast.Compare)):
            raise InputError(f"{what} {text!r}: {type(n).__name__} is not allowed")
    return used - set(_UNITS)


def _number(x):
    """``x`` (a number or an array of them) in NumPy floating point, where x / 0 is ±inf or NaN
    and not an exception as it is for Python's floats."""
    try:
        v = np.asarray(x, np.float64)
    except OverflowError:  # an integer of hundreds of digits
        return np.float64(np.inf if x > 0 else -np.inf)
    return v[()]  # a NumPy scalar for a number, the array itself otherwise


def _value(node: ast.AST, env: Mapping[str, object]):
    if isinstance(node, ast.Constant):
        return _number(node.value)
    if isinstance(node, ast.Name):
        return _number(_UNITS[node.id] if node.id in _UNITS else env[node.id])
    if isinstance(node, ast.UnaryOp):
        v = _value(node.operand, env)
        return -v if isinstance(node.op, ast.USub) else v
    if isinstance(node, ast.BinOp):
        return _BINARY[type(node.op)](_value(node.left, env), _value(node.right, env))
    if isinstance(node, ast.Call):  # abs, checked by _names
        return np.abs(_value(node.args[0], env))
    raise AssertionError(type(node).__name__)  # excluded by _names


def _operands(node: ast.AST) -> list[ast.AST]:
    if isinstance(node, ast.BinOp):
        return [node.left, node.right]
    if isinstance(node, ast.UnaryOp):
        return [node.operand]
    if isinstance(node, ast.Call):
        return [node.args[0]]
    return []


def _fault(node: ast.AST, env: Mapping[str, object]) -> str:
    """What makes ``node`` not finite at ``env``, in words: its innermost part whose operands
    are finite and whose value is not (a division by zero, an overflow, a number too large for
    floating point, or a name's value)."""
    part = node
    while bad := [c for c in _operands(part) if not np.all(np.isfinite(_value(c, env)))]:
        part = bad[0]
    if isinstance(part, ast.Name):
        return f"{part.id} is not finite"
    if isinstance(part, ast.Constant):
        why = "too large for floating point"
    elif isinstance(part, ast.BinOp) and isinstance(part.op, ast.Div) and np.any(_value(part.right, env) == 0):
        why = "division by zero"
    else:
        why = "overflow"
    return why if part is node else f"{why} in {ast.unparse(part)}"


@dataclass(frozen=True)
class Expression:
    """An arithmetic expression of numbers, pressures (``150kPa``) and known names."""

    text: str
    tree: ast.AST
    names: frozenset[str]

    @classmethod
    def parse(cls, text: str, known, what: str = "expression") -> "Expression":
        tree = _parse(text, what)
        if isinstance(tree, ast.Compare):
            raise InputError(f"{what} {text!r} must be a value, not a comparison")
        return cls.checked(text, tree, known, what)

    @classmethod
    def checked(cls, text: str, tree: ast.AST, known, what: str, whole: str | None = None) -> "Expression":
        """An expression of ``tree`` whose nodes are of the accepted kinds and whose constant
        parts are finite (``whole``: the text that errors quote, when ``tree`` is part of it)."""
        quoted = whole or text
        names = _names(tree, set(known), what, quoted)
        with np.errstate(all="ignore"):
            _check_constants(tree, names, what, quoted)
        return cls(text, tree, frozenset(names))

    def __call__(self, env: Mapping[str, object]):
        """The value at ``env`` (name -> a number or an array): a NumPy float or array, ±inf or
        NaN where the arithmetic fails; never an exception."""
        with np.errstate(all="ignore"):
            return _value(self.tree, env)

    def fault(self, env: Mapping[str, object]) -> str:
        """Why the value at ``env`` is not finite, in words (``overflow in p0 * 1e+305``)."""
        with np.errstate(all="ignore"):
            return _fault(self.tree, env)


@dataclass(frozen=True)
class Criterion:
    """A stopping criterion ``left OP right`` (OP one of < <= > >=), at least one side using a
    column of the result table; evaluated on arrays of rows, true where it is met."""

    text: str
    left: Expression
    op: str
    right: Expression

    @classmethod
    def parse(cls, text: str, columns, constants=(), what: str = "until") -> "Criterion":
        tree = _parse(text, what)
        if not (isinstance(tree, ast.Compare) and len(tree.ops) == 1 and type(tree.ops[0]) in _COMPARE):
            raise InputError(f"{what} {text!r} must be one comparison 'column OP expression' with "
                             f"OP among < <= > >=")
        known = set(columns) | set(constants)
        sides = []
        for node in (tree.left, tree.comparators[0]):
            sides.append(Expression.checked(ast.unparse(node), node, known, what, text))
        if not (sides[0].names | sides[1].names) & set(columns):
            raise InputError(f"{what} {text!r} compares no column of the result (columns: "
                             f"{', '.join(columns)})")
        return cls(text, sides[0], _COMPARE[type(tree.ops[0])][0], sides[1])

    @property
    def names(self) -> frozenset[str]:
        return self.left.names | self.right.names

    def __call__(self, env: Mapping[str, object]) -> np.ndarray:
        fn = next(f for s, f in _COMPARE.values() if s == self.op)
        with np.errstate(invalid="ignore"):
            return np.asarray(fn(self.left(env), self.right(env)), bool)
