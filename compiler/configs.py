"""The arm's configuration, declared once: which of the eight closed-form solutions of a
six-axis arm with a spherical wrist a pose target means (KRL's Status and Turn, RAPID's
confdata, FANUC's config), and which turn of the axes that can turn more than once.

* Three **groups**, each a bit of the configuration id that the kinematics compute
  (``runtime.motion.kinematics``, which takes its bits from here): the shoulder
  (``front`` | ``back``: :data:`SHOULDER_BACK`), the elbow (``elbow_up`` | ``elbow_down``:
  :data:`ELBOW_DOWN`), the wrist (``noflip`` | ``flip``: :data:`WRIST_FLIP`). A group left
  out of ``config(...)`` is free: the solution nearest where the move starts chooses it.
* **Turns** of A1, A4 and A6 (:data:`TURN_AXES`): turn ``k`` of an axis value ``q`` (deg)
  means ``-180 + 360 k <= q < 180 + 360 k`` (:func:`turn_of`, :func:`turn_range`).

The words are contextual: they mean these words only inside ``config(...)`` (a program
may have variables called ``front`` or ``flip``). :class:`Config` is the value of the
language's type ``config``; :func:`format_config` writes one as source text and
:func:`config_of` gives the full configuration of joint values. The object code's
``MAKE_CONFIG`` operand (which words a ``config(...)`` names, and whether turns follow on
the stack) is :func:`operand_of` / :func:`from_operand` / :func:`operand_problem`.

Imports nothing of the compiler or the runtime: the values, the checker, the object code,
the kinematics and the planner read it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Sequence

__all__ = ["CONTEXTUAL_NAME", "Config", "ELBOW_DOWN", "GROUPS", "Group", "MAX_OPERAND", "SHOULDER_BACK", "TURN_AXES",
           "TURN_TOL", "TURNS_FLAG", "WORDS", "WRIST_FLIP", "config_of", "describe", "format_config", "from_operand",
           "group_problem", "in_turn", "markdown", "operand_of", "operand_problem", "operand_text", "turn_of", "turn_problem", "turn_range", "value_problem",
           "words_text"]

SHOULDER_BACK = 1
ELBOW_DOWN = 2
WRIST_FLIP = 4

#: The constructor's name; a program's own declaration of it shadows the constructor.
CONTEXTUAL_NAME = "config"


@dataclass(frozen=True)
class Group:
    """One of the three choices: ``field`` (its :class:`Config` field), ``bit`` (of the
    configuration id), ``words`` (clear, set: what ``config(...)`` says), ``meanings``
    (clear, set: what messages say), ``what`` (the group, as messages name it) and
    ``doc`` (what the set word means, geometrically)."""

    field: str
    bit: int
    words: tuple[str, str]
    meanings: tuple[str, str]
    what: str
    doc: str


GROUPS: tuple[Group, ...] = (
    Group("shoulder", SHOULDER_BACK, ("front", "back"), ("front", "back"), "the shoulder",
          "the wrist centre lies behind axis 1: on the far side of axis 1 from the direction of the shoulder "
          "offset (link 1's x axis); `front`: on the same side"),
    Group("elbow", ELBOW_DOWN, ("elbow_up", "elbow_down"), ("elbow up", "elbow down"), "the elbow",
          "the elbow (axis 3) lies below the line from axis 2 to the wrist centre, in the arm's plane; below "
          "as the world sees it (the base's z up), in the back configuration too; `elbow_up`: above it"),
    Group("wrist", WRIST_FLIP, ("noflip", "flip"), ("wrist not flipped", "wrist flipped"), "the wrist",
          "sin(theta5) < 0, theta5 the DH angle of axis 5 (A5 times its direction, plus its theta_offset: A5 < 0 on the "
          "Lola 15); `noflip`: sin(theta5) > 0"),
)

#: word -> (its group, 0 for the group's first word, 1 for its second).
WORDS: dict[str, tuple[Group, int]] = {word: (group, value) for group in GROUPS for value, word in
                                       enumerate(group.words)}

#: The main axes (indices) whose turns ``config(..., T1, T4, T6)`` names: A1, A4, A6.
TURN_AXES: tuple[int, int, int] = (0, 3, 5)

#: deg: a value this close to a turn's interval counts as in it (a turn boundary, +-180 +
#: 360 k, is where a computed joint value may come out on either side by rounding).
TURN_TOL = 1e-6

#: The ``MAKE_CONFIG`` operand: two bits per group (0 free, 1 its first word, 2 its
#: second), the shoulder's lowest; TURNS_FLAG: three integer turns are on the stack.
TURNS_FLAG = 1 << 6
MAX_OPERAND = (1 << 7) - 1

_INT_MIN, _INT_MAX = -(2 ** 63), 2 ** 63 - 1


def turn_of(q: float) -> int:
    """The turn ``k`` of an axis value ``q`` (deg): ``-180 + 360 k <= q < 180 + 360 k``."""
    return math.floor((q + 180.0) / 360.0)


def turn_range(k: int) -> tuple[float, float]:
    """The axis values (deg) of turn ``k``: from ``-180 + 360 k`` up to (not including) ``180 + 360 k``."""
    return -180.0 + 360.0 * k, 180.0 + 360.0 * k


def in_turn(q: float, k: int) -> bool:
    """Whether ``q`` is in turn ``k``, within :data:`TURN_TOL` of its interval."""
    lo, hi = turn_range(k)
    return lo - TURN_TOL <= q < hi + TURN_TOL


@dataclass(frozen=True, slots=True)
class Config:
    """A value of type ``config``: each group's choice (0 its first word, 1 its second,
    None free) and the turns of A1, A4, A6 (None: each nearest where the move starts)."""

    shoulder: int | None = None
    elbow: int | None = None
    wrist: int | None = None
    turns: tuple[int, int, int] | None = None

    @property
    def mask(self) -> int:
        """The bits of the configuration id that this configuration names."""
        return sum(g.bit for g in GROUPS if getattr(self, g.field) is not None)

    @property
    def bits(self) -> int:
        """The named bits' values (a configuration id's, where this one names them)."""
        return sum(g.bit for g in GROUPS if getattr(self, g.field) == 1)

    def matches(self, config_id: int) -> bool:
        """Whether the configuration ``config_id`` (0..7) has every group this one names."""
        return config_id & self.mask == self.bits

    @property
    def free(self) -> bool:
        """Nothing named: the default rule, as without a configuration."""
        return self.mask == 0 and self.turns is None

    def __str__(self) -> str:
        return format_config(self)


def format_config(config: Config) -> str:
    """``config`` as source text: ``config(front, elbow_up, flip, 0, 0, -1)``, ``config(flip)``,
    ``config()``."""
    parts = [g.words[getattr(config, g.field)] for g in GROUPS if getattr(config, g.field) is not None]
    if config.turns is not None:
        parts += [str(k) for k in config.turns]
    return f"{CONTEXTUAL_NAME}({', '.join(parts)})"


def words_text(config: Config) -> str:
    """What ``config`` names, as messages say it: ``"back, wrist flipped"``; ``"nothing"``."""
    parts = [g.meanings[getattr(config, g.field)] for g in GROUPS if getattr(config, g.field) is not None]
    return ", ".join(parts) or "nothing"


def describe(config_id: int) -> str:
    """``"front, elbow up, wrist not flipped"`` ... for a configuration id 0..7."""
    return ", ".join(g.meanings[1 if config_id & g.bit else 0] for g in GROUPS)


def config_of(config_id: int, joints: Sequence[float]) -> Config:
    """The full configuration of joint values (the main axes first) whose configuration
    id (0..7, what ``Kinematics.configuration`` gives) is ``config_id``: every group, and
    the turns of A1, A4 and A6."""
    if type(config_id) is not int or not 0 <= config_id <= 7:
        raise ValueError(f"a configuration id is an integer 0..7, not {config_id!r}")
    values = tuple(joints)
    if len(values) <= max(TURN_AXES):
        raise ValueError(f"expected at least {max(TURN_AXES) + 1} joint values, got {len(values)}")
    groups = [1 if config_id & g.bit else 0 for g in GROUPS]
    return Config(*groups, turns=tuple(turn_of(float(values[i])) for i in TURN_AXES))


def group_problem(config: Config, config_id: int) -> tuple[Group, int] | None:
    """The first group ``config`` names differently from ``config_id``: (group, the value
    named), or None."""
    for g in GROUPS:
        named = getattr(config, g.field)
        if named is not None and named != (1 if config_id & g.bit else 0):
            return g, named
    return None


def turn_problem(config: Config, limits: Sequence[tuple[float, float]], names: Sequence[str]) -> str | None:
    """Why a named turn cannot be: its values miss the axis's limits (``limits`` and
    ``names`` of the main axes), e.g. ``"A6 turn 1 means 180..540 deg, outside its limits
    -350..350"``; None when every turn has some value within them."""
    if config.turns is None:
        return None
    for axis, k in zip(TURN_AXES, config.turns):
        lo, hi = limits[axis]
        start, end = turn_range(k)
        if end <= lo - TURN_TOL or start > hi + TURN_TOL:
            return f"{names[axis]} turn {k} means {start:g}..{end:g} deg, outside its limits {lo:g}..{hi:g}"
    return None


def value_problem(config: object) -> str | None:
    """What is wrong with ``config`` as a value of type ``config`` (one made from
    untrusted object code), or None."""
    if not isinstance(config, Config):
        return f"not a configuration: {type(config).__name__}"
    for g in GROUPS:
        v = getattr(config, g.field)
        if v is not None and (type(v) is not int or v not in (0, 1)):
            return f"{g.field} must be 0 ({g.words[0]}), 1 ({g.words[1]}) or nil (free), not {v!r:.30}"
    turns = config.turns
    if turns is not None:
        if type(turns) is not tuple or len(turns) != len(TURN_AXES):
            return "turns must be three integers (A1, A4, A6) or nil"
        for k in turns:
            if type(k) is not int or not _INT_MIN <= k <= _INT_MAX:
                return f"a turn must be a 64-bit integer, not {k!r:.30}"
    return None


def operand_of(config: Config, turns: bool) -> int:
    """The ``MAKE_CONFIG`` operand of ``config(...)``'s words (``config``'s groups) and
    whether its three turns follow on the stack."""
    value = TURNS_FLAG if turns else 0
    for i, g in enumerate(GROUPS):
        named = getattr(config, g.field)
        if named is not None:
            value |= (1 + named) << (2 * i)
    return value


def operand_problem(value: int) -> str | None:
    """What is wrong with a ``MAKE_CONFIG`` operand, or None."""
    if not 0 <= value <= MAX_OPERAND:
        return f"{value} is out of range (0..{MAX_OPERAND})"
    for i, g in enumerate(GROUPS):
        if (value >> (2 * i)) & 3 == 3:
            return (f"{value} names {g.what} twice (bits {2 * i}-{2 * i + 1} are 3: 0 free, 1 {g.words[0]}, "
                    f"2 {g.words[1]})")
    return None


def from_operand(value: int, turns: tuple | None = None) -> Config:
    """The configuration a valid ``MAKE_CONFIG`` operand names, with ``turns`` (popped)."""
    groups = []
    for i in range(len(GROUPS)):
        field = (value >> (2 * i)) & 3
        groups.append(field - 1 if field else None)
    return Config(*groups, turns=tuple(turns) if turns is not None else None)


def operand_text(value: int) -> str:
    """A valid ``MAKE_CONFIG`` operand as the disassembler shows it: ``config(front, flip,
    T1, T4, T6)`` (the turns are popped)."""
    text = format_config(from_operand(value))
    if value & TURNS_FLAG:
        text = text[:-1] + (", " if text[-2] != "(" else "") + "T1, T4, T6)"
    return text


def markdown() -> str:
    """docs/language.md's table of the words (``python -m runtime.cli.docgen --write``)."""
    lines = ["| group | words | bit of the configuration id (set by the second word) | the second word means |",
             "|---|---|---|---|"]
    for g in GROUPS:
        lines.append(f"| {g.what[4:]} | `{g.words[0]}` \\| `{g.words[1]}` | {g.bit} | {g.doc} |")
    return "\n".join(lines) + "\n"
