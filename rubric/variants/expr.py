"""Constraint rules of a variant space: a small arithmetic language, parsed once and evaluated without eval().

A rule is one Python-like expression over parameter names and the lesson's fixed quantities, e.g.
`low_lane_friction < table_friction < high_lane_friction` or `close(fine_dt / base_substeps, coarse_dt / more_substeps)`.
Only numbers, names, + - * / ** and unary minus, comparisons, and/or/not, and the functions below are allowed, so a
reviewer reads exactly what is checked and a lesson file can never run code.
"""

from __future__ import annotations

import ast
import math
import operator
from collections.abc import Callable, Mapping

# Relative tolerance of close() and integral(): float representation error only (1.5 / 0.01 = 150.00000000000003).
REL_TOL = 1e-9


def _close(a: float, b: float) -> bool:
    return math.isclose(a, b, rel_tol=REL_TOL, abs_tol=1e-12)


def _integral(x: float) -> bool:
    return abs(x - round(x)) <= REL_TOL * max(1.0, abs(x))


FUNCTIONS: dict[str, Callable] = {"abs": abs, "min": min, "max": max, "close": _close, "integral": _integral}

_BINARY = {ast.Add: operator.add, ast.Sub: operator.sub, ast.Mult: operator.mul, ast.Div: operator.truediv,
           ast.Pow: operator.pow}
_COMPARE = {ast.Lt: operator.lt, ast.LtE: operator.le, ast.Gt: operator.gt, ast.GtE: operator.ge,
            ast.Eq: operator.eq, ast.NotEq: operator.ne}


class RuleError(ValueError):
    """A rule that is not in the constraint language, or names something the space does not define."""


def parse_rule(text: str, names: set[str]) -> ast.Expression:
    """Parse `text` and check every node against the language; RuleError says what is not allowed and where."""
    try:
        tree = ast.parse(text, mode="eval")
    except SyntaxError as exc:
        raise RuleError(f"not an expression: {exc.msg} at column {exc.offset}") from None
    for node in ast.walk(tree):
        if isinstance(node, ast.Name):
            if node.id not in names and node.id not in FUNCTIONS:
                raise RuleError(f"unknown name {node.id!r}; known: {', '.join(sorted(names))}")
        elif isinstance(node, ast.Call):
            if not isinstance(node.func, ast.Name) or node.func.id not in FUNCTIONS or node.keywords:
                raise RuleError(f"only the functions {', '.join(FUNCTIONS)} may be called, with positional arguments")
        elif isinstance(node, ast.Constant):
            if isinstance(node.value, bool) or not isinstance(node.value, (int, float)):
                raise RuleError(f"only numbers may appear as constants, not {node.value!r}")
        elif isinstance(node, ast.BinOp) and type(node.op) not in _BINARY:
            raise RuleError(f"operator {type(node.op).__name__} is not allowed")
        elif isinstance(node, ast.UnaryOp) and not isinstance(node.op, (ast.USub, ast.Not)):
            raise RuleError(f"operator {type(node.op).__name__} is not allowed")
        elif isinstance(node, ast.Compare) and any(type(op) not in _COMPARE for op in node.ops):
            raise RuleError("only < <= > >= == != comparisons are allowed")
        elif not isinstance(node, (ast.Expression, ast.Name, ast.Call, ast.Constant, ast.BinOp, ast.UnaryOp,
                                   ast.Compare, ast.BoolOp, ast.And, ast.Or, ast.Load, *_BINARY, *_COMPARE,
                                   ast.USub, ast.Not)):
            raise RuleError(f"{type(node).__name__} is not allowed in a constraint rule")
    return tree


def rule_names(tree: ast.Expression) -> list[str]:
    """The parameter and fixed-quantity names a rule reads, in order of first appearance."""
    seen = []
    for node in ast.walk(tree):
        if isinstance(node, ast.Name) and node.id not in FUNCTIONS and node.id not in seen:
            seen.append(node.id)
    return seen


def evaluate_rule(tree: ast.Expression, values: Mapping[str, float]) -> bool:
    """The rule's truth for these values; division by zero counts as the rule failing, never as a crash."""
    try:
        return bool(_eval(tree.body, values))
    except (ZeroDivisionError, OverflowError):
        return False


def _eval(node: ast.AST, values: Mapping[str, float]):
    if isinstance(node, ast.Constant):
        return node.value
    if isinstance(node, ast.Name):
        return values[node.id]
    if isinstance(node, ast.BinOp):
        return _BINARY[type(node.op)](_eval(node.left, values), _eval(node.right, values))
    if isinstance(node, ast.UnaryOp):
        operand = _eval(node.operand, values)
        return -operand if isinstance(node.op, ast.USub) else not operand
    if isinstance(node, ast.BoolOp):
        if isinstance(node.op, ast.And):
            return all(_eval(v, values) for v in node.values)
        return any(_eval(v, values) for v in node.values)
    if isinstance(node, ast.Compare):
        left = _eval(node.left, values)
        for op, right_node in zip(node.ops, node.comparators):
            right = _eval(right_node, values)
            if not _COMPARE[type(op)](left, right):
                return False
            left = right
        return True
    if isinstance(node, ast.Call):
        return FUNCTIONS[node.func.id](*(_eval(a, values) for a in node.args))
    raise RuleError(f"{type(node).__name__} is not allowed")  # parse_rule already refused it
