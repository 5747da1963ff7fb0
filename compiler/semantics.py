"""What L-IRL's operators and built-in functions compute.

One definition for the compiler's constant folding and the runtime's VM, so a value
folded at compile time is exactly the value the robot would have computed. Errors are
:class:`EvalError` with a message for the operator; callers add the source line.
"""
from __future__ import annotations

import math

from .values import Joint, Pose, Position, Quat, Rpy


class EvalError(Exception):
    """A run-time error in an expression (division by zero, a domain error...)."""


def _is_int(x) -> bool:
    return isinstance(x, int) and not isinstance(x, bool)


def idiv(a: int, b: int) -> int:
    """``a div b``: integer division truncating toward zero (Pascal)."""
    if b == 0:
        raise EvalError("division by zero (div)")
    q = abs(a) // abs(b)
    return q if (a >= 0) == (b >= 0) else -q


def imod(a: int, b: int) -> int:
    """``a mod b``: the remainder of ``div``, with the sign of ``a``."""
    if b == 0:
        raise EvalError("division by zero (mod)")
    return a - b * idiv(a, b)


def divide(a, b) -> float:
    if b == 0:
        raise EvalError("division by zero")
    return a / b


def _finite(x: float, what: str) -> float:
    if not math.isfinite(x):
        raise EvalError(f"{what} is not a finite number")
    return x


BINARY = {
    "+": lambda a, b: a + b,
    "-": lambda a, b: a - b,
    "*": lambda a, b: a * b,
    "/": divide,
    "div": idiv,
    "mod": imod,
    "=": lambda a, b: a == b,
    "<>": lambda a, b: a != b,
    "<": lambda a, b: a < b,
    "<=": lambda a, b: a <= b,
    ">": lambda a, b: a > b,
    ">=": lambda a, b: a >= b,
    "and": lambda a, b: a and b,
    "or": lambda a, b: a or b,
}


INT_MIN, INT_MAX = -(2 ** 63), 2 ** 63 - 1  # integers are 64-bit


#: Longest string value, in characters: a program that builds a longer one stops at its
#: line; the compiler and the object-code decoder refuse longer constants.
MAX_STRING_LENGTH = 10_000


def binary(op: str, a, b):
    if op == "+" and isinstance(a, str) and isinstance(b, str) and len(a) + len(b) > MAX_STRING_LENGTH:
        raise EvalError(f"string too long: joining {len(a)} and {len(b)} characters gives more than "
                        f"{MAX_STRING_LENGTH}, the longest string allowed")
    result = BINARY[op](a, b)
    if isinstance(result, float):
        _finite(result, f"the result of '{op}'")
    elif isinstance(result, int) and not isinstance(result, bool) and not INT_MIN <= result <= INT_MAX:
        raise EvalError(f"integer overflow in '{op}': the result is outside the 64-bit integer range")
    return result


def unary(op: str, a):
    if op == "-":
        if a == INT_MIN and not isinstance(a, float):
            raise EvalError("integer overflow in '-': the result is outside the 64-bit integer range")
        return -a
    if op == "+":
        return a
    return not a


def _domain(fn, x, name: str, low: float, high: float) -> float:
    if not low <= x <= high:
        raise EvalError(f"{name}({x:g}) is undefined: the argument must be within {low:g}..{high:g}")
    return fn(x)


def _round(x) -> int:
    """Round half away from zero (what an operator expects; not Python's banker's rounding)."""
    _finite(float(x), "round's argument")
    return int(math.floor(abs(x) + 0.5)) * (1 if x >= 0 else -1)


def _sqrt(x) -> float:
    if x < 0:
        raise EvalError(f"sqrt({x:g}) is undefined for a negative number")
    return math.sqrt(x)


def _tan(x) -> float:
    if math.isclose(math.fmod(abs(x), 180.0), 90.0, abs_tol=1e-12):
        raise EvalError(f"tan({x:g}) is undefined")
    return math.tan(math.radians(x))


BUILTIN_FUNCTIONS = {
    "sin": lambda x: math.sin(math.radians(x)),
    "cos": lambda x: math.cos(math.radians(x)),
    "tan": _tan,
    "asin": lambda x: math.degrees(_domain(math.asin, x, "asin", -1.0, 1.0)),
    "acos": lambda x: math.degrees(_domain(math.acos, x, "acos", -1.0, 1.0)),
    "atan2": lambda y, x: math.degrees(math.atan2(y, x)),
    "sqrt": _sqrt,
    "abs": abs,
    "min": min,
    "max": max,
    "round": _round,
    "trunc": lambda x: int(_finite(float(x), "trunc's argument")),
}


def call_builtin(name: str, args):
    result = BUILTIN_FUNCTIONS[name](*args)
    if isinstance(result, float):
        _finite(result, f"{name}(...)")
    elif isinstance(result, int) and not INT_MIN <= result <= INT_MAX:
        raise EvalError(f"integer overflow in {name}(...): the result is outside the 64-bit integer range")
    return result


def make_quat(w: float, x: float, y: float, z: float) -> Quat:
    norm = math.sqrt(w * w + x * x + y * y + z * z)
    if norm < 1e-12:
        raise EvalError("quat(0, 0, 0, 0) is not a rotation")
    return Quat(w / norm, x / norm, y / norm, z / norm)


def make_joint(main, add=()) -> Joint:
    return Joint(tuple(float(v) for v in main), tuple(float(v) for v in add))


def make_pos(x, y, z) -> Position:
    return Position(float(x), float(y), float(z))


def make_rpy(r, p, y) -> Rpy:
    return Rpy(float(r), float(p), float(y))


def get_axis(joint: Joint, axis: int) -> float:
    values = joint.axes
    if not 1 <= axis <= len(values):
        raise EvalError(f"axis {axis} does not exist (the joint value has axes 1..{len(values)})")
    return values[axis - 1]


def set_axis(joint: Joint, axis: int, value) -> Joint:
    get_axis(joint, axis)
    values = list(joint.axes)
    values[axis - 1] = float(value)
    n = len(joint.main)
    return Joint(tuple(values[:n]), tuple(values[n:]))


def get_field(value, name: str) -> float:
    position = value.position if isinstance(value, Pose) else value
    return getattr(position, name)


def check_index(index: int, low: int, length: int) -> int:
    """The 0-based position of ``index`` in an array ``low..low+length-1``."""
    i = index - low
    if not 0 <= i < length:
        raise EvalError(f"index {index} is outside the array bounds {low}..{low + length - 1}")
    return i
