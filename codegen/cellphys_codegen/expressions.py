"""Descriptor expressions: Python syntax, checked node by node, evaluated on SymPy objects."""
import ast

import sympy as sp

from .errors import DescriptorError
from .kinematics import BODY_ATTRIBUTES, FUNCTIONS, Body, World

_ALLOWED = (
    ast.Expression, ast.BinOp, ast.UnaryOp, ast.Call, ast.Name, ast.Load, ast.Attribute,
    ast.Compare, ast.Constant, ast.Add, ast.Sub, ast.Mult, ast.Div, ast.Pow, ast.USub, ast.UAdd,
    ast.Gt, ast.GtE, ast.Lt, ast.LtE,
)


def evaluate(text, names, path, where):
    """Evaluate one expression string against `names` (symbols, vectors, bodies)."""
    if isinstance(text, (int, float)) and not isinstance(text, bool):
        return sp.Float(text) if isinstance(text, float) else sp.Integer(text)
    if not isinstance(text, str):
        raise DescriptorError(path, where, f"expected an expression string, got {type(text).__name__}")
    if len(text) > 4000:
        raise DescriptorError(path, where, "expression longer than 4000 characters: split it into lets")
    try:
        tree = ast.parse(text, mode="eval")
    except (SyntaxError, RecursionError) as e:
        raise DescriptorError(path, where, f"expression does not parse: {getattr(e, 'msg', type(e).__name__)} "
                              f"in {text!r}") from None
    for node in ast.walk(tree):
        if not isinstance(node, _ALLOWED):
            raise DescriptorError(path, where, f"{type(node).__name__} is not allowed in {text!r}")
        if isinstance(node, ast.Name) and node.id not in names and node.id not in FUNCTIONS:
            raise DescriptorError(path, where, f"unknown name {node.id!r} in {text!r}")
        if isinstance(node, ast.Call) and not (isinstance(node.func, ast.Name) and node.func.id in FUNCTIONS):
            raise DescriptorError(path, where, f"only the primitives {sorted(FUNCTIONS)} can be called in {text!r}")
        if isinstance(node, ast.Attribute):
            if not (isinstance(node.value, ast.Name) and isinstance(names.get(node.value.id), (Body, World))):
                raise DescriptorError(path, where, f"attributes are only read from bodies (a, b) in {text!r}")
            if node.attr not in BODY_ATTRIBUTES:
                raise DescriptorError(path, where, f"a body has no attribute {node.attr!r} "
                                      f"(known: {sorted(BODY_ATTRIBUTES)}) in {text!r}")
        if isinstance(node, ast.BinOp) and isinstance(node.op, ast.Pow) and not (
                isinstance(node.right, ast.Constant) or
                (isinstance(node.right, ast.UnaryOp) and isinstance(node.right.operand, ast.Constant))):
            raise DescriptorError(path, where, f"exponents must be constants in {text!r}")
        if isinstance(node, ast.Constant) and isinstance(node.value, (int, float)) and abs(node.value) > 1e30:
            raise DescriptorError(path, where, f"constant {node.value!r} is out of range in {text!r}")
        if isinstance(node, ast.Compare) and len(node.ops) != 1:
            raise DescriptorError(path, where, f"chained comparisons are not allowed in {text!r}")
        if isinstance(node, ast.Constant) and (isinstance(node.value, bool) or not isinstance(node.value, (int, float))):
            raise DescriptorError(path, where, f"constant {node.value!r} is not a number in {text!r}")
    env = dict(FUNCTIONS)
    env.update(names)
    try:
        value = eval(compile(tree, str(path), "eval"), {"__builtins__": {}}, env)  # noqa: S307 (validated above)
    except (TypeError, ValueError, AttributeError, sp.ShapeError, ZeroDivisionError, RecursionError) as e:
        raise DescriptorError(path, where, f"cannot evaluate {text!r}: {e or type(e).__name__}") from None
    if isinstance(value, (int, float)):
        value = sp.sympify(value)
    return value
