"""What L-IRL's operators and built-in functions compute.

One definition for the compiler's constant folding and the runtime's VM, so a value
folded at compile time is exactly the value the robot would have computed. Errors are
:class:`EvalError` with a message for the operator; callers add the source line.
"""
from __future__ import annotations

import decimal
import math
import re

from . import geometry
from .values import Config, Joint, Pose, Position, Quat, Rpy


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


# ---- geometry: positions as vectors, poses as frames ---------------------------------------
# Kinds are the L-IRL type names; "number" is an integer or a real.

def kind(value) -> str:
    """The L-IRL kind of a run-time value, as the operator tables name it."""
    if isinstance(value, bool):
        return "bool"
    if isinstance(value, (int, float)):
        return "number"
    return _KINDS.get(type(value), type(value).__name__)


_KINDS = {Position: "position", Pose: "pose", Rpy: "orientation", Quat: "orientation", Joint: "joint", str: "string",
          Config: "config"}


def _quat(o) -> tuple[float, float, float, float]:
    return geometry.rpy_to_quat(o.roll, o.pitch, o.yaw) if isinstance(o, Rpy) else (o.w, o.x, o.y, o.z)


def _orientation(q, rpy: bool):
    """A rotation as an ``rpy`` (when ``rpy``) or a unit ``quat`` with w >= 0."""
    return Rpy(*geometry.quat_to_rpy(q)) if rpy else Quat(*geometry.unit(q))


def _vector(p: Position) -> tuple[float, float, float]:
    return (p.x, p.y, p.z)


def _position(v) -> Position:
    x, y, z = v
    for c in (x, y, z):
        _finite(c, "a coordinate of the result")
    return Position(x, y, z)


def _plus(a: Position, b: Position) -> Position:
    return _position((a.x + b.x, a.y + b.y, a.z + b.z))


def _minus(a: Position, b: Position) -> Position:
    return _position((a.x - b.x, a.y - b.y, a.z - b.z))


def _scale(p: Position, k) -> Position:
    return _position((p.x * k, p.y * k, p.z * k))


def _shrink(p: Position, k) -> Position:
    if k == 0:
        raise EvalError("division by zero")
    return _position((p.x / k, p.y / k, p.z / k))


def compose(a: Pose, b: Pose) -> Pose:
    """``a * b``: the pose ``b``, given in the frame ``a``, in the frame ``a`` is given in;
    with ``b``'s configuration (the target placed in a frame: ``pallet * place``)."""
    qa = _quat(a.orientation)
    moved = geometry.rotate(qa, _vector(b.position))
    rpy = isinstance(a.orientation, Rpy) and isinstance(b.orientation, Rpy)
    return Pose(_plus(a.position, _position(moved)),
                _orientation(geometry.quat_multiply(qa, _quat(b.orientation)), rpy), b.config)


def transform(a: Pose, p: Position) -> Position:
    """``a * p``: the point ``p``, given in the frame ``a``, in the frame ``a`` is given in."""
    return _plus(a.position, _position(geometry.rotate(_quat(a.orientation), _vector(p))))


def inverse(a):
    """``inv(a)``: the inverse of a pose (``a * inv(a)`` is the identity; it names no
    configuration) or of an orientation; the orientation stays ``rpy`` or ``quat`` as it was."""
    if isinstance(a, Pose):
        qi = geometry.quat_conjugate(_quat(a.orientation))
        x, y, z = geometry.rotate(qi, _vector(a.position))
        return Pose(_position((-x, -y, -z)), _orientation(qi, isinstance(a.orientation, Rpy)))
    return _orientation(geometry.quat_conjugate(_quat(a)), isinstance(a, Rpy))


def tool_offset(a: Pose, p: Position) -> Pose:
    """``tool_offset(a, p)``: ``a`` moved by ``p`` along its own (the tool's) axes; the
    orientation and the configuration unchanged (``a * pose(p, rpy(0, 0, 0))``, but ``a``'s
    configuration)."""
    return Pose(transform(a, p), a.orientation, a.config)


def distance(a, b) -> float:
    """``distance(a, b)``: between two positions, or the positions of poses (mm)."""
    pa = a.position if isinstance(a, Pose) else a
    pb = b.position if isinstance(b, Pose) else b
    return math.dist(_vector(pa), _vector(pb))


#: The geometric operators: (operator, left kind, right kind) -> (result kind, function,
#: what it means). The checker types expressions with it, the VM computes with it, and
#: docs/language.md's table is generated from it.
GEOMETRY: dict[tuple[str, str, str], tuple[str, object, str]] = {
    ("+", "position", "position"): ("position", _plus, "vector sum"),
    ("-", "position", "position"): ("position", _minus, "vector difference"),
    ("*", "position", "number"): ("position", _scale, "scaled"),
    ("*", "number", "position"): ("position", lambda k, p: _scale(p, k), "scaled"),
    ("/", "position", "number"): ("position", _shrink, "scaled by 1/k; k = 0 is an error"),
    ("+", "pose", "position"): ("pose", lambda a, p: Pose(_plus(a.position, p), a.orientation, a.config),
                                "offset along the base frame's axes (orientation and configuration unchanged)"),
    ("-", "pose", "position"): ("pose", lambda a, p: Pose(_minus(a.position, p), a.orientation, a.config),
                                "offset against the base frame's axes (orientation and configuration unchanged)"),
    ("*", "pose", "pose"): ("pose", compose, "composition: the right pose, given in the frame of the left "
                                             "one, in the left one's frame; the right one's configuration"),
    ("*", "pose", "position"): ("position", transform, "the point, given in the frame of the pose, in the pose's "
                                                       "frame"),
    ("*", "orientation", "orientation"): ("orientation", lambda a, b: _orientation(
        geometry.quat_multiply(_quat(a), _quat(b)), isinstance(a, Rpy) and isinstance(b, Rpy)),
        "composition: the right rotation first, then the left one"),
}
GEOMETRY_OPS = frozenset(op for op, _l, _r in GEOMETRY)
_GEOMETRIC = (Position, Pose, Rpy, Quat)


def geometry_markdown() -> str:
    """docs/language.md's table of the geometric operators and built-ins (python -m
    runtime.cli.docgen), from :data:`GEOMETRY` and :data:`GEOMETRIC_BUILTINS`."""
    lines = ["| expression | result | meaning |", "|---|---|---|"]
    for (op, left, right), (result, _fn, doc) in GEOMETRY.items():
        lines.append(f"| {left} `{op}` {right} | {result} | {doc} |")
    lines.append("| `-` position | position | the opposite vector |")
    docs = {"inv": "the inverse: `a * inv(a)` is the identity (of a pose: no configuration)",
            "distance": "the distance between the two points (mm; of poses, their positions)",
            "tool_offset": "the pose moved by the position along its own (the tool's) axes, orientation and "
                           "configuration unchanged"}
    for name, forms in GEOMETRIC_BUILTINS.items():
        for wanted, result in forms:
            lines.append(f"| `{name}`({', '.join(w.replace('|', ' or ') for w in wanted)}) | {result} | {docs[name]} |")
    return "\n".join(lines) + "\n"


def geometric(op: str, a, b):
    """``a op b`` by :data:`GEOMETRY`; EvalError for a pair it does not define."""
    entry = GEOMETRY.get((op, kind(a), kind(b)))
    if entry is None:
        raise EvalError(f"'{op}' is not defined for {kind(a)} {op} {kind(b)}")
    return entry[1](a, b)


_ARITHMETIC = frozenset({"+", "-", "*", "/", "div", "mod"})
_NUMBERS = (int, float)


def binary(op: str, a, b):
    if op in GEOMETRY_OPS and (isinstance(a, _GEOMETRIC) or isinstance(b, _GEOMETRIC)):
        return geometric(op, a, b)
    if op in _ARITHMETIC and not (type(a) in _NUMBERS and type(b) in _NUMBERS) and \
            not (op == "+" and type(a) is str and type(b) is str):
        # (the compiler never makes such object code: a string repeated or an array joined
        # from hand-made code must not allocate at will)
        raise EvalError(f"'{op}' is not defined for {kind(a)} {op} {kind(b)}")
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
    if op == "-" and isinstance(a, Position):
        return Position(-a.x, -a.y, -a.z)
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


def _text(s: str, what: str) -> str:
    if len(s) > MAX_STRING_LENGTH:
        raise EvalError(f"{what}: the string would be {len(s)} characters long, over {MAX_STRING_LENGTH}, the longest "
                        "string allowed")
    return s


def _str_part(s: str, first: int, count: int) -> str:
    """``count`` characters of ``s`` from character ``first`` (from 1)."""
    if count < 0 or not 1 <= first <= len(s) + 1 or first + count - 1 > len(s):
        last = f"..{first + count - 1}" if count > 1 else ""
        raise EvalError(f"str_part: characters {first}{last} of a string of {len(s)} (first 1..{len(s) + 1}, "
                        f"and at most {max(len(s) - first + 1, 0)} from there)" if count >= 0 else
                        f"str_part: a count of {count} characters (0 or more)")
    return s[first - 1:first - 1 + count]


def _num_to_str(x, decimals: int) -> str:
    """``x`` with ``decimals`` digits after the point, rounded half away from zero (as
    round()), no exponent; never "-0"."""
    if not 0 <= decimals <= MAX_DECIMALS:
        raise EvalError(f"num_to_str: {decimals} decimals (0..{MAX_DECIMALS})")
    value = decimal.Decimal(repr(_finite(float(x), "num_to_str's argument")) if isinstance(x, float) else int(x))
    exact = decimal.Context(prec=800)  # (every digit of the largest real, and the decimals)
    text = format(value.quantize(decimal.Decimal(1).scaleb(-decimals), rounding=decimal.ROUND_HALF_UP, context=exact),
                  "f")
    if text.startswith("-") and not text.strip("-0."):
        text = text[1:]
    return _text(text, "num_to_str")


def _str_to_num(s: str) -> float:
    """The number a string spells (an L-IRL number: digits, a point, an exponent, a sign;
    spaces around it), as a real."""
    if not _NUMBER_TEXT.fullmatch(s):
        shown = s if len(s) <= 40 else s[:37] + "..."
        raise EvalError(f"str_to_num: {shown!r} is not a number")
    return _finite(float(s), "str_to_num's result")


#: The most decimals num_to_str gives.
MAX_DECIMALS = 15
_NUMBER_TEXT = re.compile(r"\s*[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?\s*")

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
    "inv": inverse,
    "distance": distance,
    "tool_offset": tool_offset,
    "str_len": len,
    "str_part": _str_part,
    "str_find": lambda s, part: s.find(part) + 1,
    "num_to_str": _num_to_str,
    "str_to_num": _str_to_num,
}

#: The built-in functions on strings: name -> (the parameters' types, the result's type)
#: (docs/language.md, "Strings"). The names are not reserved: a program's own function of
#: the same name is called instead.
STRING_BUILTINS: dict[str, tuple[tuple[str, ...], str]] = {
    "str_len": (("string",), "integer"),
    "str_part": (("string", "integer", "integer"), "string"),
    "str_find": (("string", "string"), "integer"),
    "num_to_str": (("real", "integer"), "string"),
    "str_to_num": (("string",), "real"),
}

#: The built-in functions on geometric values: name -> [(argument kinds, result kind)]
#: (the others take numbers). "position|pose": either.
GEOMETRIC_BUILTINS: dict[str, tuple[tuple[tuple[str, ...], str], ...]] = {
    "inv": ((("pose",), "pose"), (("orientation",), "orientation")),
    "distance": ((("position|pose", "position|pose"), "real"),),
    "tool_offset": ((("pose", "position"), "pose"),),
}


def geometric_result(name: str, kinds: tuple[str, ...]) -> str | None:
    """The result kind of geometric built-in ``name`` given arguments of ``kinds`` (by
    :data:`GEOMETRIC_BUILTINS`), or None when it is not defined for them."""
    for wanted, result in GEOMETRIC_BUILTINS[name]:
        if len(wanted) == len(kinds) and all(k in w.split("|") for k, w in zip(kinds, wanted)):
            return result
    return None


def call_builtin(name: str, args):
    if name in GEOMETRIC_BUILTINS:  # (checked at compile time; object code is checked again here)
        kinds = tuple(kind(arg) for arg in args)
        if geometric_result(name, kinds) is None:
            raise EvalError(f"{name}({', '.join(kinds)}) is not defined")
    result = BUILTIN_FUNCTIONS[name](*args)
    if isinstance(result, float):
        _finite(result, f"{name}(...)")
    elif isinstance(result, int) and not INT_MIN <= result <= INT_MAX:
        raise EvalError(f"integer overflow in {name}(...): the result is outside the 64-bit integer range")
    return result


def make_quat(w: float, x: float, y: float, z: float) -> Quat:
    """``quat(w, x, y, z)`` normalised (any size: compiler.geometry.normalise)."""
    unit = geometry.normalise((w, x, y, z))
    if unit is None:
        raise EvalError("quat(0, 0, 0, 0) is not a rotation")
    return Quat(*unit)


def make_joint(main, add=()) -> Joint:
    return Joint(tuple(float(v) for v in main), tuple(float(v) for v in add))


def make_pos(x, y, z) -> Position:
    return Position(float(x), float(y), float(z))


def make_rpy(r, p, y) -> Rpy:
    return Rpy(float(r), float(p), float(y))


def make_pose(position: Position, orientation, config: Config | None = None) -> Pose:
    """``pose(position, orientation[, config])``: a configuration that names nothing
    (``config()``) is no configuration, so such a pose is the pose without one."""
    return Pose(position, orientation, None if config is None or config.free else config)


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
