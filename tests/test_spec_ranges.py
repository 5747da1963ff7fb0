"""Every number a specification gives has a range the runtime can use (issue 26, fault 6):
``irl check`` refuses a value outside it, naming the file, the key and the allowed range;
any specification it accepts runs the paper's program (programs/test.irl) on the
simulated robot without nan and without a fault caused by its numbers. The same for the
configuration's numbers (robot.velocity_limit_scale, initialization.home_speed).

Before, ``max_acceleration``, ``gear_ratio``, ``max_velocity``, ``max_jerk``, ``kp``,
``following_error_limit`` and ``speed_ptp`` = 5e-324 all passed the check and faulted
only at run time (nan positions, a servo that never settles).
"""
from __future__ import annotations

import dataclasses
import io
import math
import os
import re
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, Phase, example, given, settings
from hypothesis import strategies as st

from compiler import clauses, params
from compiler.driver import compile_source
from compiler.spec import SpecError, parse_spec
from runtime.cli.main import Environment, main
from runtime.loop.system import RobotSystem, RunOptions

from conftest import ROOT, examples
SPEC_TEXT = (ROOT / "programs" / "lola15.spc").read_text(encoding="utf-8")
TEST_IRL = (ROOT / "programs" / "test.irl").read_text(encoding="utf-8")
AXIS = params.section_params("axis")
CONTROLLER = params.spec_section("controller")
SAFETY = params.spec_section("safety")
SIMULATION = params.spec_section("simulation")
#: The configuration's numbers the property sets (a component's settings, applied before the run).
CONFIGURATION = [("robot", "velocity_limit_scale"), ("initialization", "home_speed")]
#: A run the time limit ends: slow but healthy (the smallest limits move the paper's 90 deg
#: at 0.1 deg/s); anything else that ends a run early is a fault.
MAX_TIME = 40.0
TIME_LIMIT = f"the run did not end within {MAX_TIME:g} s"


def _set(text: str, table: str, key: str, value, index: int | None = None) -> str:
    """``text`` with ``key = value`` in ``[table]`` (or the ``index``-th ``[[axis]]``)."""
    rendered = repr(value) if isinstance(value, float) else str(value)
    if index is None:
        if f"\n[{table}]" not in text:  # (a table the file leaves out: all its defaults)
            text = text.rstrip("\n") + f"\n\n[{table}]\n"
        head, sep, body = text.partition(f"\n[{table}]")
        rest = body.split("\n[", 1)
        section = rest[0]
        if re.search(rf"\n{key} = ", section):
            section = re.sub(rf"\n{key} = [^\n]*", f"\n{key} = {rendered}", section)
        else:
            section = section + f"\n{key} = {rendered}"
        return head + sep + section + ("\n[" + rest[1] if len(rest) > 1 else "")
    parts = text.split("[[axis]]")
    part = parts[index + 1]
    if re.search(rf"\n{key} = ", part):
        part = re.sub(rf"\n{key} = [^\n]*", f"\n{key} = {rendered}", part)
    else:
        part = part.replace("\nkind = ", f"\n{key} = {rendered}\nkind = ", 1)
    parts[index + 1] = part
    return "[[axis]]".join(parts)


def _least(param):
    """The smallest value ``param`` accepts (next above an open lower bound)."""
    if param.kind == "integer":
        return param.low + (1 if param.low_open else 0)
    return math.nextafter(float(param.low), math.inf) if param.low_open else float(param.low)


def _values(param) -> st.SearchStrategy:
    """Across the whole accepted range, its bounds included (log-uniform for wide ones)."""
    low, high = _least(param), param.high
    if param.kind == "integer":
        return st.one_of(st.sampled_from([low, high]), st.integers(low, high))
    if low > 0 and high / low > 100:
        inside = st.floats(math.log(low), math.log(high)).map(lambda x: min(max(math.exp(x), low), high))
    else:
        inside = st.floats(low, high)
    return st.one_of(st.sampled_from([low, high]), inside)


#: What the property changes: (table, key, axis or None, the accepted range's declaration).
KNOBS = ([("axis", key, i, AXIS[key]) for key in ("max_velocity", "max_acceleration", "max_jerk", "gear_ratio",
                                                   "encoder_counts", "sensor_window", "search_velocity")
          for i in range(6)]
         + [("controller", "kp", None, CONTROLLER["kp"]),
            ("controller", "following_error_limit", None, CONTROLLER["following_error_limit"])]
         + [("safety", key, None, SAFETY[key]) for key in ("max_drive_drift", "plausibility_distance")]
         + [("simulation", key, None, SIMULATION[key]) for key in ("drive_time_constant", "end_stop_margin")]
         + [(component, key, None, params.section_params(component)[key]) for component, key in CONFIGURATION])


def _apply(text: str, settings: dict, table: str, key: str, value, index) -> str:
    """``value`` for the knob: in the specification's text, or (a component's) in ``settings``."""
    if table in params.COMPONENTS:
        settings.setdefault(table, {})[key] = value
        return text
    return _set(text, table, key, value, index)


@st.composite
def specs(draw) -> tuple[str, dict]:
    """The paper's robot with some of its numbers anywhere in their accepted ranges, and
    the configuration's settings (component -> name -> value) it runs with."""
    text, settings_ = SPEC_TEXT, {}
    chosen = draw(st.lists(st.sampled_from(range(len(KNOBS))), min_size=1, max_size=8, unique=True))
    for k in chosen:
        table, key, index, param = KNOBS[k]
        text = _apply(text, settings_, table, key, draw(_values(param), label=f"{table}.{key}"), index)
    for clause in ("speed_ptp", "acc_ptp"):  # the defaults: accepted at their bounds too
        rng = clauses.BY_NAME[clause].ranges[0]
        text = _set(text, "defaults", clause, draw(st.sampled_from([rng.low, rng.high, 0.5])))
    return text, settings_


def _system(text: str, settings_: dict, max_time: float):
    """(a RobotSystem with this specification and these settings, each checked against its
    declared range as runtime.config does, test.irl compiled for it), or None if the
    specification is refused (with a message that names the file and the range)."""
    try:
        parse_spec(text, "variant.spc")
    except SpecError as exc:
        assert "expected" in str(exc) and "variant.spc" in str(exc), str(exc)
        return None
    checked = {component: {key: params.section_params(component)[key].check(value) for key, value in values.items()}
               for component, values in settings_.items()}
    with tempfile.TemporaryDirectory() as tmp:
        (Path(tmp) / "lola15.spc").write_text(text, encoding="utf-8")
        result = compile_source(TEST_IRL, str(Path(tmp) / "test.irl"))
    assert result.ok, [d.message for d in result.diagnostics]
    system = RobotSystem(result.spec, RunOptions(max_time=max_time))
    system.apply_settings(checked)
    return system, result.program


def run_paper_program(text: str, settings_: dict | None = None) -> dict | None:
    """The summary of test.irl's run with this specification (and these settings); None if
    refused."""
    made = _system(text, settings_ or {}, MAX_TIME)
    if made is None:
        return None
    system, program = made
    return system.run(program)


def _lowest() -> tuple[str, dict]:
    text, settings_ = SPEC_TEXT, {}
    text = _set(text, "simulation", "max_drive_offset", 0.0)  # (the least max_drive_drift accepts no more)
    for table, key, index, param in KNOBS:
        if key not in ("encoder_counts", "gear_ratio"):  # (the lowest of both: too coarse an encoder, refused)
            text = _apply(text, settings_, table, key, _least(param), index)
    return text, settings_


def _highest() -> tuple[str, dict]:
    text, settings_ = SPEC_TEXT, {}
    for table, key, index, param in KNOBS:
        if key == "encoder_counts":  # the finest encoder and gear together are refused
            text = _set(text, table, key, round(params.MAX_COUNTS_PER_UNIT * 360 / AXIS["gear_ratio"].high), index)
        elif key == "drive_time_constant":  # (the longest lag the highest kp accepts)
            text = _set(text, table, key, params.MAX_KP_LAG / CONTROLLER["kp"].high)
        elif key != "search_velocity":
            text = _apply(text, settings_, table, key, param.high, index)
    return text, settings_


@settings(max_examples=8, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(case=specs())
@example(case=_lowest())
@example(case=_highest())
def test_any_specification_irl_check_accepts_runs_the_paper_program(case):
    summary = run_paper_program(*case)
    if summary is None:
        return
    assert summary["fault"] is None or summary["fault"].endswith(TIME_LIMIT), summary["fault"]
    assert all(math.isfinite(x) for x in summary["final_position"]), summary["final_position"]
    assert math.isfinite(summary["max_following_error"])
    for move in summary["moves"]:
        assert math.isfinite(move["planned_duration"]) and move["planned_duration"] > 0


@pytest.mark.long
def test_each_number_at_the_least_it_accepts_runs_the_paper_program_without_a_fault():
    """One number at a time at the smallest value its range accepts (every axis alike):
    test.irl runs without nan or a fault (slow at the least speeds: the time limit ends
    it). Before, plausibility_distance = 5e-324 (0 excluded) faulted homing (no encoder
    count for a travel that small), max_drive_drift = 5e-324 faulted calibration."""
    seen = set()
    for table, key, _index, param in KNOBS:
        if (table, key) in seen or key in ("gear_ratio", "encoder_counts"):  # (least of each: a refused encoder)
            continue
        seen.add((table, key))
        text, settings_ = SPEC_TEXT, {}
        if key == "max_drive_drift":  # (the simulated drives drift no more than it accepts)
            text = _set(text, "simulation", "max_drive_offset", 0.0)
        least_value = _least(param)
        default = parse_spec(SPEC_TEXT, "lola15.spc")
        tau = default.simulation.drive_time_constant
        if key == "following_error_limit":  # (the least the per-axis rule accepts with the paper's axes)
            least_value = max([least_value] + [params.least_following_error_limit(a, tau, default.controller.kp)
                                               for a in default.axes])
        if key == "plausibility_distance":
            least_value = max([least_value] + [params.least_plausibility_distance(a, tau) for a in default.axes])
        for index in range(6) if table == "axis" else [None]:
            text = _apply(text, settings_, table, key, least_value, index)
        if key == "kp":  # (the servo's slower settling needs a longer in_position_timeout: the least the rule accepts)
            text = _set(text, "safety", "in_position_timeout", _least_timeout(parse_spec(_set(
                text, "safety", "in_position_timeout", SAFETY["in_position_timeout"].high), "variant.spc")))
        if key == "max_acceleration":  # (the coarsest encoder the resolution rule accepts with it)
            factor = SAFETY["acceleration_factor"].default
            for index, axis in enumerate(default.axes):
                least = params.least_counts_per_unit(_least(param), factor)
                text = _set(text, "axis", "encoder_counts", math.ceil(least * 360 / axis.gear_ratio), index)
        summary = run_paper_program(text, settings_)
        assert summary is not None, (table, key)
        fault = summary["fault"]
        assert fault is None or fault.endswith(TIME_LIMIT), (table, key, least_value, fault)
        assert all(math.isfinite(x) for x in summary["final_position"]), (table, key)


def _least_timeout(spec) -> float:
    """The least [safety] in_position_timeout the rules accept for ``spec``'s axes and gains, at
    least its default (rounded up to the ms)."""
    c, s, tau = spec.controller, spec.safety, spec.simulation.drive_time_constant
    least = max(params.least_in_position_timeout(a, tau, c.kp, c.ki, s.in_position_window, s.in_position_time)
                for a in spec.axes)
    return max(SAFETY["in_position_timeout"].default, math.ceil(least * 1000) / 1000)


def run_to_end_of_homing(text: str, settings_: dict, max_time: float) -> dict | None:
    """Power-up, calibration and homing of test.irl's cycle with this specification (None
    if refused): ``{"completed", "fault", "time", "final"}``. The specification's numbers
    matter up to here (the program's moves are checked against them before they run)."""
    made = _system(text, settings_, max_time)
    if made is None:
        return None
    system, program = made
    system.begin(program, None)
    sup = system.supervisor
    system.executive.run(lambda: sup.done or system.init.completed, int(max_time / params.TICK))
    outcome = {"completed": system.init.completed, "fault": sup.fault, "time": system.clock.tick_time,
               "final": list(system.robot.positions)}
    if not sup.done:
        sup.request_stop("the test has seen homing end")
        system.executive.run(lambda: sup.done, int(5.0 / params.TICK))
    system.finish()
    return outcome


#: The numbers that take their least or greatest value in combination (each axis its own):
#: every knob but the speeds below, which make homing take many minutes at their least.
#: (max_velocity too: the searches go at most half of it.)
SLOW = {"search_velocity", "velocity_limit_scale", "home_speed", "max_velocity"}
#: IRL_SPEC_SEARCH=N: N examples (default 4, scaled by IRL_EXAMPLES_SCALE), the slow speeds drawn too,
#: homing given an hour.
SEARCH = int(os.environ.get("IRL_SPEC_SEARCH", "0") or 0)
HOMING_TIME = 3600.0 if SEARCH else 30.0
EXTREME_KNOBS = [knob for knob in KNOBS + [("safety", "acceleration_factor", None, SAFETY["acceleration_factor"]),
                                           ("simulation", "max_drive_offset", None, SIMULATION["max_drive_offset"])]
                 if SEARCH or knob[1] not in SLOW]


@st.composite
def extreme_specs(draw) -> tuple[str, dict]:
    """The paper's robot with every knob at the least or the greatest value it accepts,
    all six axes: where a rule across keys (compiler.params) narrows a range, the least
    or greatest the rule accepts given the others."""
    text, settings_, chosen = SPEC_TEXT, {}, {}
    for table, key, index, param in EXTREME_KNOBS:
        value = draw(st.sampled_from([_least(param), param.high]), label=f"{table}.{key}[{index}]")
        chosen[(table, key, index)] = value
    factor = chosen[("safety", "acceleration_factor", None)]
    kp = chosen[("controller", "kp", None)]
    tau_most = params.MAX_KP_LAG / kp
    chosen[("simulation", "drive_time_constant", None)] = min(chosen[("simulation", "drive_time_constant", None)],
                                                              tau_most)
    spec = parse_spec(SPEC_TEXT, "lola15.spc")
    offset_most = min(params.greatest_drive_offset(chosen[("axis", "max_acceleration", i)], factor)
                      for i in range(6))
    for i, axis in enumerate(spec.axes):
        window = chosen[("axis", "sensor_window", i)]
        gear_least = params.least_gear_ratio(dataclasses.replace(axis, sensor_window=window))
        gear = max(chosen[("axis", "gear_ratio", i)], gear_least)
        least = params.least_counts_per_unit(chosen[("axis", "max_acceleration", i)], factor)
        fine = draw(st.booleans(), label=f"finest encoder [{i}]")
        target = params.MAX_COUNTS_PER_UNIT if fine else least
        counts = min(max(math.floor(target * 360 / gear) if fine else math.ceil(target * 360 / gear),
                         AXIS["encoder_counts"].low), AXIS["encoder_counts"].high)
        if counts * gear / 360 < least:  # (the most counts at this gear too coarse: a finer gear)
            gear = least * 360 / counts * (1 + 1e-12)
        if counts * gear / 360 > params.MAX_COUNTS_PER_UNIT:
            gear = params.MAX_COUNTS_PER_UNIT * 360 / counts * (1 - 1e-12)
        chosen[("axis", "gear_ratio", i)], chosen[("axis", "encoder_counts", i)] = gear, counts
    tau = chosen[("simulation", "drive_time_constant", None)]
    plausible = max(params.least_plausibility_distance(dataclasses.replace(
        axis, gear_ratio=chosen[("axis", "gear_ratio", i)], encoder_counts=chosen[("axis", "encoder_counts", i)],
        max_velocity=chosen.get(("axis", "max_velocity", i), axis.max_velocity),
        max_acceleration=chosen[("axis", "max_acceleration", i)],
        search_velocity=min(chosen.get(("axis", "search_velocity", i), axis.search_velocity),
                            chosen.get(("axis", "max_velocity", i), axis.max_velocity))), tau)
        for i, axis in enumerate(spec.axes))
    chosen[("safety", "plausibility_distance", None)] = max(chosen[("safety", "plausibility_distance", None)],
                                                            plausible)
    following = max(params.least_following_error_limit(dataclasses.replace(
        axis, max_acceleration=chosen[("axis", "max_acceleration", i)]), tau, kp) for i, axis in enumerate(spec.axes))
    chosen[("controller", "following_error_limit", None)] = max(
        chosen[("controller", "following_error_limit", None)], following)
    offset = chosen[("simulation", "max_drive_offset", None)]
    drift = chosen[("safety", "max_drive_drift", None)]
    offset = min(offset, offset_most, SAFETY["max_drive_drift"].high - params.DRIFT_RESOLUTION)
    chosen[("simulation", "max_drive_offset", None)] = offset
    chosen[("safety", "max_drive_drift", None)] = max(drift, offset + params.DRIFT_RESOLUTION)
    margin = chosen[("simulation", "end_stop_margin", None)]
    for (table, key, index), value in chosen.items():
        if table == "axis" and key == "search_velocity":
            value = min(value, chosen[("axis", "max_velocity", index)])
        text = _apply(text, settings_, table, key, value, index)
    assert margin > SAFETY["limit_tolerance"].default
    # the in_position_timeout the servo's settling needs with these axes and gains (at most 60 s: else refused)
    timeout = _least_timeout(parse_spec(_set(text, "safety", "in_position_timeout",
                                             SAFETY["in_position_timeout"].high), "variant.spc"))
    return _set(text, "safety", "in_position_timeout", min(timeout, SAFETY["in_position_timeout"].high)), settings_


#: Each example runs homing on the simulated clock (about a second): a failure is reported
#: as drawn (no shrinking, which reruns homing hundreds of times), its knobs printed.
@pytest.mark.long
@settings(max_examples=SEARCH or examples(4), deadline=None, phases=[Phase.explicit, Phase.generate],
          suppress_health_check=[HealthCheck.too_slow], print_blob=True)
@given(case=extreme_specs())
def test_every_extreme_combination_irl_check_accepts_homes_without_a_fault(case):
    """Every knob at an end of its accepted range, together, all six axes: the cycle gets
    through calibration and homing to the start position, with no fault and no nan, within
    a minute of simulated time. Before: 50 counts per deg faulted homing (acceleration
    check), a gear ratio of 1 to 3 ran homing's index search past the axis's min, the
    greatest max_drive_offset faulted at the start of homing, and kp 5 with the finest
    encoder did not settle at the start position."""
    spec = parse_spec(case[0], "variant.spc")
    # the index searches go up to two motor revolutions at the search velocity (half of max_velocity at most)
    searches = sum(2 * a.index_spacing / min(a.search_velocity, 0.5 * a.max_velocity) for a in spec.axes)
    outcome = run_to_end_of_homing(*case, max_time=HOMING_TIME + searches)
    assert outcome is not None, "an extreme combination made to fit the rules was refused"
    assert outcome["fault"] is None and outcome["completed"], outcome
    assert all(math.isfinite(x) for x in outcome["final"]), outcome


TINY = 5e-324


@pytest.mark.parametrize("table,key,index", [
    ("axis", "max_acceleration", 0), ("axis", "gear_ratio", 1), ("axis", "max_velocity", 2),
    ("axis", "max_jerk", 3), ("controller", "kp", None), ("controller", "following_error_limit", None),
    ("defaults", "speed_ptp", None), ("defaults", "acc_ptp", None), ("robot", "max_speed", None),
    ("robot", "max_acceleration", None), ("axis", "search_velocity", 4), ("axis", "sensor_window", 5),
    ("safety", "max_drive_drift", None), ("safety", "plausibility_distance", None),
    ("simulation", "drive_time_constant", None), ("simulation", "end_stop_margin", None)])
def test_irl_check_names_a_value_below_its_range(tmp_path, table, key, index):
    (tmp_path / "lola15.spc").write_text(_set(SPEC_TEXT, table, key, TINY, index), encoding="utf-8")
    (tmp_path / "test.irl").write_text(TEST_IRL, encoding="utf-8")
    out, err = io.StringIO(), io.StringIO()
    code = main(["check", str(tmp_path / "test.irl")], Environment(stdout=out, stderr=err))
    text = out.getvalue() + err.getvalue()
    assert code == 1, text
    where = f"axis[{index + 1}].{key}" if table == "axis" else f"{table}.{key}"
    assert f"lola15.spc: {where}: expected" in text, text
    assert "5e-324" in text and "Traceback" not in text
    assert re.search(r"expected (a number |an integer )?[0-9.e+]+ <=|>= [0-9.]+|<= x", text), text


@pytest.mark.parametrize("key", ["max_speed", "max_acceleration"])
@pytest.mark.parametrize("value", [1e305, 1e299, 1e7])
def test_irl_check_names_a_tool_limit_above_its_range(tmp_path, key, value):
    """[robot] max_speed and max_acceleration have an upper bound of their own (20 m/s,
    50 g): a value above it is named with its range. (When they moved into the parameter
    table, a value from 1e300 up to the largest float was accepted for a while.)"""
    (tmp_path / "lola15.spc").write_text(_set(SPEC_TEXT, "robot", key, value), encoding="utf-8")
    (tmp_path / "test.irl").write_text(TEST_IRL, encoding="utf-8")
    out, err = io.StringIO(), io.StringIO()
    code = main(["check", str(tmp_path / "test.irl")], Environment(stdout=out, stderr=err))
    text = out.getvalue() + err.getvalue()
    assert code == 1 and f"lola15.spc: robot.{key}: expected" in text and "<=" in text, text


def test_a_too_coarse_encoder_is_refused_with_its_resolution():
    text = _set(_set(SPEC_TEXT, "axis", "gear_ratio", 1.0, 0), "axis", "encoder_counts", 4096, 0)
    with pytest.raises(SpecError, match=r"axis\[1\]\.gear_ratio: .*11\.38 counts per deg: expected 50 to 20000"):
        parse_spec(text, "coarse.spc")


@pytest.mark.parametrize("changes, where, words", [
    ([("safety", "max_drive_drift", 0.5)], "safety.max_drive_drift",
     "expected at least [simulation] max_drive_offset + 0.1 (0.6"),
    ([("safety", "limit_tolerance", 2.0), ("simulation", "end_stop_margin", 2.0)], "simulation.end_stop_margin",
     "expected more than [safety] limit_tolerance (2"),
    ([("controller", "kp", 100.0), ("simulation", "drive_time_constant", 0.01)], "simulation.drive_time_constant",
     "expected at most 0.5 / [controller] kp (0.005 s"),
    # (before: accepted, and a search from rest at 5 deg/s faulted the encoder plausibility
    # check, the command 0.05 deg ahead of a drive that lags 0.01 s)
    # (before: accepted; the move to the start position, at 2000 deg/s^2, drew 0.114 deg of following
    # error from a drive that lags 0.01 s with kp 10)
    ([("controller", "kp", 10.0), ("simulation", "drive_time_constant", 0.01), ("controller", "following_error_limit", 0.3)],
     "controller.following_error_limit", "expected at least 0.4 deg for A1 ([simulation] drive_time_constant 0.01 x its max_acceleration 400 / [controller] kp 10"),
    ([("simulation", "drive_time_constant", 0.01), ("safety", "plausibility_distance", 0.05)],
     "safety.plausibility_distance", "expected at least 0.08109 deg for A1 (one count, 1 / 1820, + [simulation] drive_time_constant 0.01 x 8.055"),
])
def test_the_rules_between_tables_are_named(changes, where, words):
    """Numbers each within its range that do not go together (the simulated drives drift
    more than calibration accepts; the end stops inside where the safety lets the arm
    rest; a drive's lag the servo's gain overshoots on) are refused, naming the key."""
    text = SPEC_TEXT
    for table, key, value in changes:
        text = _set(text, table, key, value)
    with pytest.raises(SpecError) as error:
        parse_spec(text, "pair.spc")
    assert f"pair.spc: {where}: {words}" in str(error.value), str(error.value)


def test_every_axis_and_robot_key_is_declared_once_with_its_default():
    """Issue 28: the [[axis]] and [robot] keys are compiler.params' (section axis, robot):
    every field of an axis is declared there (the DH table aside), and a table that leaves
    a key out gets the declared default (sensor_position's relative to home)."""
    from compiler.spec import Axis, Spec

    declared = params.section_params("axis")
    for field in dataclasses.fields(Axis):
        if field.name != "dh":
            assert field.name in declared, f"axis.{field.name} is not declared in compiler.params"
            assert field.default is dataclasses.MISSING, f"Axis.{field.name} writes a default of its own"
    robot = params.spec_section("robot")
    assert {"name", "description", "max_speed", "max_acceleration"} <= set(robot)
    assert "velocity_limit_scale" not in robot  # the component's, a configuration key
    text = ('[robot]\nname = "r"\n[[axis]]\nname = "a1"\nkind = "revolute"\nmin = -90.0\nmax = 90.0\n'
            'max_velocity = 100.0\nmax_acceleration = 500.0\nmax_jerk = 5000.0\n')
    spec = parse_spec(text, "min.spc")
    axis = spec.axes[0]
    for name, param in declared.items():
        if param.default is not None and name != "sensor_position" and param.kind != "pose":
            assert getattr(axis, name) == param.default, name
    assert axis.sensor_position == axis.home + declared["sensor_position"].default
    for name in ("description", "max_speed", "max_acceleration"):
        assert getattr(spec, name) == robot[name].default, name
    assert isinstance(spec, Spec)
    with pytest.raises(SpecError, match=r"robot\.max_speed: expected a number 0\.1 <= x <= 20000 \(mm/s\), got 0\.05"):
        parse_spec(text.replace('name = "r"\n', 'name = "r"\nmax_speed = 0.05\n'), "min.spc")
