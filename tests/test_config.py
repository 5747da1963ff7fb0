"""Component configurations (runtime/config.py).

* The sample ``programs/lola15.toml`` loads, and its configurations are the runtime's defaults.
* ``based_on`` is resolved key by key, through chains, in any file order.
* Every error path gives a ConfigError whose message names the file, the configuration
  and the key, and says what was expected and what was found.
* Robustness (hypothesis, derandomized): random text, random TOML-ish documents written by a
  tiny TOML writer, and random Python values for ``validate_settings`` raise nothing but
  ConfigError; valid generated configurations load and read back.
"""
from __future__ import annotations

import math
import os
import re
from pathlib import Path

import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from compiler.params import component_params
from runtime.config import (
    COLUMNS,
    SCHEMA,
    ConfigError,
    Configuration,
    Configurations,
    load_configurations,
    parse_configurations,
    schema_markdown,
    validate_settings,
)

from conftest import ROOT, examples
SAMPLE = ROOT / "programs" / "lola15.toml"

FUZZ = dict(deadline=None, derandomize=True, database=None,
            suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large,
                                   HealthCheck.filter_too_much, HealthCheck.large_base_example])

STANDARD = {
    "servo": {"kp": 40.0, "ki": 2.0, "following_error_limit": 2.0},
    "robot": {"velocity_limit_scale": 1.0},
    "trajectory": {"budget": 200, "period": 0.005},
    "initialization": {"period": 0.005, "home_speed": 0.2},
    "report": {"period": 0.01, "columns": ["sens_pos", "desi_pos", "out_vel", "following_error", "tcp"]},
}


def error_of(text: str, name: str = "t.toml") -> str:
    """The message of the ConfigError that parsing ``text`` raises."""
    with pytest.raises(ConfigError) as info:
        parse_configurations(text, name)
    return str(info.value)


def one(component: str, body: str, name: str = "c") -> str:
    """A file with one configuration ``name`` whose ``component`` table is ``body``."""
    return f"[configurations.{name}.{component}]\n{body}\n"


# ---- the sample file ------------------------------------------------------------------------------

def test_sample_loads():
    configs = load_configurations(SAMPLE)
    assert isinstance(configs, Configurations)
    assert configs.path == SAMPLE
    assert configs.default == "standard"
    assert configs.names() == ["standard", "gentle"]
    assert configs["standard"] == Configuration("standard", STANDARD)
    assert configs.default_configuration is configs["standard"]


def test_sample_gentle_is_based_on_standard():
    gentle = load_configurations(SAMPLE)["gentle"]
    expected = {component: dict(values) for component, values in STANDARD.items()}
    expected["servo"]["kp"] = 25.0
    expected["robot"]["velocity_limit_scale"] = 0.5
    expected["report"]["period"] = 0.02
    assert gentle.settings == expected
    assert gentle.get("servo", "kp") == 25.0
    assert gentle.get("servo", "ki") == 2.0
    assert gentle.get("report", "columns") == list(COLUMNS)


def test_sample_standard_matches_the_component_defaults():
    """'standard' is the runtime's current behaviour: the values the components use when nothing is set."""
    import inspect
    import tomllib

    from runtime.loop.components.initialization import Initialization
    from runtime.loop.components.report import Report
    from runtime.loop.components.trajectory import TrajectoryGenerator
    from runtime.loop.vm import VM

    def default(function, parameter):
        return inspect.signature(function).parameters[parameter].default

    standard = load_configurations(SAMPLE)["standard"]
    controller = tomllib.loads((ROOT / "programs" / "lola15.spc").read_text(encoding="utf-8"))["controller"]
    for key in ("kp", "ki", "following_error_limit"):
        assert standard.get("servo", key) == controller[key]
    assert standard.get("trajectory", "budget") == default(VM.__init__, "budget")
    assert standard.get("trajectory", "period") == default(TrajectoryGenerator.__init__, "period")
    assert standard.get("initialization", "period") == default(Initialization.__init__, "period")
    assert standard.get("report", "period") == default(Report.__init__, "period")


def test_sample_comments_explain_every_key():
    text = SAMPLE.read_text(encoding="utf-8")
    for line in text.splitlines():
        if re.match(r"\s*[a-z_]+\s*=", line):
            assert "#" in line, f"no comment on: {line}"


def test_sample_sets_every_schema_key_in_standard():
    standard = load_configurations(SAMPLE)["standard"]
    assert {c: set(keys) for c, keys in standard.settings.items()} == {c: set(keys) for c, keys in SCHEMA.items()}


# ---- the API --------------------------------------------------------------------------------------

def test_get_with_default():
    config = parse_configurations(one("servo", "kp = 12"))["c"]
    assert config.get("servo", "kp") == 12.0
    assert config.get("servo", "ki") is None
    assert config.get("servo", "ki", 2.0) == 2.0
    assert config.get("report", "period", 0.01) == 0.01


def test_default_is_the_first_configuration_when_not_given():
    text = one("servo", "kp = 10", "b") + one("servo", "kp = 20", "a")
    configs = parse_configurations(text)
    assert configs.default == "b"
    assert configs.names() == ["b", "a"]
    assert configs.path is None


def test_default_given():
    configs = parse_configurations('default = "a"\n' + one("servo", "kp = 10", "b") + one("servo", "kp = 20", "a"))
    assert configs.default == "a"
    assert configs.default_configuration.get("servo", "kp") == 20.0


def test_container_protocol():
    configs = load_configurations(SAMPLE)
    assert "gentle" in configs and "fast" not in configs and 3 not in configs and [] not in configs
    assert list(configs) == ["standard", "gentle"]
    assert len(configs) == 2


def test_unknown_configuration_name():
    configs = load_configurations(SAMPLE)
    with pytest.raises(ConfigError, match=r"^no configuration 'fast' in .*lola15\.toml; known: standard, gentle$"):
        configs["fast"]
    with pytest.raises(ConfigError, match=r"no configuration 'gentel' in .*lola15\.toml \(did you mean 'gentle'\?\); "
                                          r"known: standard, gentle"):
        configs["gentel"]
    with pytest.raises(ConfigError, match=r"no configuration \[\] in <config>"):
        parse_configurations(one("servo", "kp = 10"))[[]]


def test_config_error_is_a_value_error():
    assert issubclass(ConfigError, ValueError)


def test_empty_configuration_and_empty_component():
    configs = parse_configurations("[configurations.bare]\n[configurations.empty.servo]\n")
    assert configs["bare"].settings == {}
    assert configs["empty"].settings == {"servo": {}}


def test_ints_become_floats_for_numbers_and_stay_ints_for_integers():
    config = parse_configurations(one("servo", "kp = 40\nki = 0") + one("trajectory", "budget = 7\nperiod = 1"))["c"]
    assert type(config.get("servo", "kp")) is float and config.get("servo", "kp") == 40.0
    assert type(config.get("servo", "ki")) is float
    assert type(config.get("trajectory", "budget")) is int
    assert type(config.get("trajectory", "period")) is float and config.get("trajectory", "period") == 1.0


def test_periods_are_normalized_to_whole_milliseconds():
    config = parse_configurations(one("report", "period = 0.0050000000001"))["c"]
    assert config.get("report", "period") == 0.005
    config = parse_configurations(one("report", "period = 0.0009999999995"))["c"]
    assert config.get("report", "period") == 0.001
    config = parse_configurations(one("report", "period = 1.0000000005"))["c"]
    assert config.get("report", "period") == 1.0


@pytest.mark.parametrize("period", [0.001, 0.002, 0.003, 0.007, 0.01, 0.1, 0.3, 0.999, 1.0, 1])
def test_valid_periods(period):
    assert parse_configurations(one("report", f"period = {period}"))["c"].get("report", "period") == float(period)


def test_validate_settings_normalizes():
    result = validate_settings({"servo": {"kp": 12, "ki": 0}, "report": {"columns": ("out_vel",)}}, "client")
    assert result == {"servo": {"kp": 12.0, "ki": 0.0}, "report": {"columns": ["out_vel"]}}
    assert type(result["servo"]["kp"]) is float


def test_validate_settings_errors_start_with_where():
    with pytest.raises(ConfigError, match=r"^client: configuration 'x': servo\.kp: expected a number 10 <= x <= 100 \(1/s\), got -1$"):
        validate_settings({"servo": {"kp": -1}}, "client: configuration 'x'")
    with pytest.raises(ConfigError, match=r"^net: trajectory\.period: expected the same period as initialization"):
        validate_settings({"trajectory": {"period": 0.005}, "initialization": {"period": 0.01}}, "net")
    with pytest.raises(ConfigError, match=r"^net: expected a table of components, got \[1, 2\]$"):
        validate_settings([1, 2], "net")
    with pytest.raises(ConfigError, match=r"^net: unknown component 3"):
        validate_settings({3: {}}, "net")
    with pytest.raises(ConfigError, match=r"^net: servo\.b'kp' \(a bytes\): unknown key"):
        validate_settings({"servo": {b"kp": 1}}, "net")


def test_validate_settings_does_not_modify_its_argument():
    given_ = {"servo": {"kp": 12}, "report": {"columns": ["out_vel"]}}
    validate_settings(given_, "net")
    assert given_ == {"servo": {"kp": 12}, "report": {"columns": ["out_vel"]}}


def test_configurations_do_not_share_mutable_values():
    configs = parse_configurations(one("report", 'columns = ["out_vel"]', "a") + '[configurations.b]\nbased_on = "a"\n')
    assert configs["a"].get("report", "columns") == configs["b"].get("report", "columns")
    assert configs["a"].get("report", "columns") is not configs["b"].get("report", "columns")


def test_schema_markdown():
    text = schema_markdown()
    lines = text.splitlines()
    assert lines[0] == "| parameter | allowed | default | safety | changes by | meaning |"
    assert lines[1] == "|---|---|---|---|---|---|"
    rows = lines[2:]
    assert len(rows) == sum(len(keys) for keys in SCHEMA.values())
    for component, keys in SCHEMA.items():
        for key, setting in keys.items():
            row = next(r for r in rows if r.startswith(f"| `{component}.{key}`"))
            assert setting.expected in row and setting.description.replace("|", "\\|") in row
            assert len(re.split(r"(?<!\\)\|", row)) == 8  # six cells
            assert ("| yes |" in row) == setting.safety


def test_schema_entries_are_complete():
    for component, keys in SCHEMA.items():
        assert keys, component
        for key, setting in keys.items():
            assert setting.type and setting.expected and setting.description and callable(setting.check), key


# ---- based_on ----------------------------------------------------------------------------------

def test_based_on_chain_resolves_key_by_key():
    text = """
[configurations.a.servo]
kp = 10.0
ki = 1.0
[configurations.a.report]
columns = ["sens_pos"]

[configurations.b]
based_on = "a"
[configurations.b.servo]
ki = 2.0
[configurations.b.trajectory]
budget = 5

[configurations.c]
based_on = "b"
[configurations.c.servo]
following_error_limit = 3.0
"""
    configs = parse_configurations(text)
    assert configs["c"].settings == {
        "servo": {"kp": 10.0, "ki": 2.0, "following_error_limit": 3.0},
        "report": {"columns": ["sens_pos"]},
        "trajectory": {"budget": 5},
    }
    assert configs["b"].settings == {"servo": {"kp": 10.0, "ki": 2.0}, "report": {"columns": ["sens_pos"]},
                                     "trajectory": {"budget": 5}}
    assert configs["a"].settings == {"servo": {"kp": 10.0, "ki": 1.0}, "report": {"columns": ["sens_pos"]}}


def test_based_on_a_later_configuration():
    text = '[configurations.first]\nbased_on = "second"\n' + one("servo", "kp = 12", "second")
    configs = parse_configurations(text)
    assert configs["first"].get("servo", "kp") == 12.0
    assert configs.default == "first"


def test_based_on_long_chain():
    n = 3000  # deeper than the recursion limit: resolution is iterative
    parts = [one("servo", "kp = 10", "c0")]
    parts += [f'[configurations.c{i}]\nbased_on = "c{i - 1}"\n' for i in range(1, n)]
    configs = parse_configurations("".join(parts))
    assert configs[f"c{n - 1}"].get("servo", "kp") == 10.0


def test_cross_field_rule_applies_after_based_on():
    text = (one("trajectory", "period = 0.005", "a") + one("initialization", "period = 0.005", "a")
            + '[configurations.b]\nbased_on = "a"\n[configurations.b.initialization]\nperiod = 0.01\n')
    message = error_of(text)
    assert message == ("t.toml: configuration 'b': trajectory.period: expected the same period as "
                       "initialization.period (0.01 s; the servo interpolates both setpoint streams with one period), "
                       "got 0.005")


def test_cross_field_rule_one_side_given_is_fine():
    configs = parse_configurations(one("trajectory", "period = 0.004") + one("initialization", "period = 0.008", "d"))
    assert configs["c"].get("trajectory", "period") == 0.004


def test_cross_field_equal_periods_after_normalization():
    text = one("trajectory", "period = 0.0050000000004") + one("initialization", "period = 0.005")
    assert parse_configurations(text)["c"].get("trajectory", "period") == 0.005


# ---- error paths ---------------------------------------------------------------------------------

def test_message_names_file_configuration_and_key():
    text = one("servo", "kp = 40.0", "standard") + '[configurations.gentle]\nbased_on = "standard"\n' \
        + "[configurations.gentle.servo]\nkp = -1\n"
    assert error_of(text, "lola15.toml") == (
        "lola15.toml: configuration 'gentle': servo.kp: expected a number 10 <= x <= 100 (1/s), got -1")


def test_unknown_component_with_suggestion():
    assert error_of(one("sevro", "kp = 10")) == (
        "t.toml: configuration 'c': unknown component 'sevro' (did you mean 'servo'?); "
        "known: servo, robot, trajectory, initialization, report")


def test_unknown_component_without_suggestion():
    assert error_of(one("gripper", "force = 1")) == (
        "t.toml: configuration 'c': unknown component 'gripper'; "
        "known: servo, robot, trajectory, initialization, report")


def test_unknown_key_with_suggestion():
    assert error_of(one("servo", "kpp = 1")) == (
        "t.toml: configuration 'c': servo.kpp: unknown key (did you mean 'kp'?); "
        "known keys of servo: kp, ki, following_error_limit")
    assert error_of(one("robot", "velocity_scale = 1")).startswith(
        "t.toml: configuration 'c': robot.velocity_scale: unknown key (did you mean 'velocity_limit_scale'?)")


def test_unknown_key_without_suggestion():
    assert error_of(one("report", "format = 'csv'")) == (
        "t.toml: configuration 'c': report.format: unknown key; known keys of report: period, columns")


def test_unknown_top_level_key():
    assert error_of('defualt = "a"\n' + one("servo", "kp = 10")) == (
        "t.toml: unknown top-level key 'defualt' (did you mean 'default'?); known: default, configurations")
    assert error_of(one("kp", "x = 1").replace("configurations.c.", "")).startswith(
        "t.toml: unknown top-level key 'kp'; known: default, configurations")


def test_component_is_not_a_table():
    assert error_of("[configurations.c]\nservo = 3\n") == (
        "t.toml: configuration 'c': servo: expected a table of settings, got 3")


def test_configuration_is_not_a_table():
    assert error_of('configurations = {c = "x"}\n') == (
        "t.toml: configuration 'c': expected a table of components, got 'x'")


def test_configurations_is_not_a_table():
    assert error_of("configurations = [1, 2]\n") == (
        "t.toml: configurations: expected a table of named configurations, got [1, 2]")


@pytest.mark.parametrize("component, body, expected", [
    ("servo", "kp = 0", "servo.kp: expected a number 10 <= x <= 100 (1/s), got 0"),
    ("servo", "kp = -2.5", "servo.kp: expected a number 10 <= x <= 100 (1/s), got -2.5"),
    ("servo", 'kp = "40"', "servo.kp: expected a number 10 <= x <= 100 (1/s), got '40'"),
    ("servo", "kp = [40]", "servo.kp: expected a number 10 <= x <= 100 (1/s), got [40]"),
    ("servo", "kp = {a = 1}", "servo.kp: expected a number 10 <= x <= 100 (1/s), got a table"),
    ("servo", "kp = 1979-05-27", "servo.kp: expected a number 10 <= x <= 100 (1/s), got 1979-05-27 (a date)"),
    ("servo", "kp = inf", "servo.kp: expected a number 10 <= x <= 100 (1/s), got inf"),
    ("servo", "kp = nan", "servo.kp: expected a number 10 <= x <= 100 (1/s), got nan"),
    ("servo", "kp = " + "9" * 400, "servo.kp: expected a number 10 <= x <= 100 (1/s), got a very large integer"),
    ("servo", "ki = -0.1", "servo.ki: expected a number 0 <= x <= 100 (1/s^2), got -0.1"),
    ("servo", "following_error_limit = 0.0", "servo.following_error_limit: expected a number 0.1 <= x <= 10 (deg or mm), got 0.0"),
    ("robot", "velocity_limit_scale = 0", "robot.velocity_limit_scale: expected a number 0.01 <= x <= 1, got 0"),
    ("robot", "velocity_limit_scale = 1.5", "robot.velocity_limit_scale: expected a number 0.01 <= x <= 1, got 1.5"),
    ("robot", "velocity_limit_scale = 5e-324", "robot.velocity_limit_scale: expected a number 0.01 <= x <= 1, got 5e-324"),
    ("initialization", "home_speed = 5e-324",
     "initialization.home_speed: expected a number 0.01 <= x <= 1, got 5e-324"),
    ("trajectory", "budget = 0", "trajectory.budget: expected an integer 1 <= x <= 10000 (instructions), got 0"),
    ("trajectory", "budget = 10001", "trajectory.budget: expected an integer 1 <= x <= 10000 (instructions), got 10001"),
    ("trajectory", "budget = 200.0", "trajectory.budget: expected an integer 1 <= x <= 10000 (instructions), got 200.0"),
    ("trajectory", 'budget = "200"', "trajectory.budget: expected an integer 1 <= x <= 10000 (instructions), got '200'"),
])
def test_wrong_values(component, body, expected):
    assert error_of(one(component, body)) == f"t.toml: configuration 'c': {expected}"


@pytest.mark.parametrize("component, key", [
    ("servo", "kp"), ("servo", "ki"), ("servo", "following_error_limit"), ("robot", "velocity_limit_scale"),
    ("trajectory", "budget"), ("trajectory", "period"), ("initialization", "period"), ("report", "period"),
])
@pytest.mark.parametrize("value", ["true", "false"])
def test_bool_rejected_for_numbers(component, key, value):
    message = error_of(one(component, f"{key} = {value}"))
    assert message.startswith(f"t.toml: configuration 'c': {component}.{key}: expected ")
    assert message.endswith(f", got {value} (a boolean)")


def test_bool_rejected_by_validate_settings():
    with pytest.raises(ConfigError, match=r"servo\.kp: expected a number 10 <= x <= 100 \(1/s\), got true \(a boolean\)"):
        validate_settings({"servo": {"kp": True}}, "net")
    with pytest.raises(ConfigError, match=r"trajectory\.budget: expected an integer 1 <= x <= 10000 \(instructions\), got true"):
        validate_settings({"trajectory": {"budget": True}}, "net")


@pytest.mark.parametrize("component", ["trajectory", "initialization", "report"])
@pytest.mark.parametrize("period, nearest", [
    ("0.0025", "0.002 or 0.003"), ("0.0051", "0.005 or 0.006"), ("0.0011", "0.001 or 0.002"),
    ("0.5005", "0.5 or 0.501"),
])
def test_period_not_a_multiple_of_the_tick(component, period, nearest):
    assert error_of(one(component, f"period = {period}")) == (
        f"t.toml: configuration 'c': {component}.period: expected a whole multiple of the 1 ms tick, got {period} "
        f"(nearest: {nearest})")


@pytest.mark.parametrize("component", ["trajectory", "initialization", "report"])
@pytest.mark.parametrize("period", ["0", "0.0", "-0.005", "0.0005", "1.001", "2", "1e300", "-1e300"])
def test_period_out_of_range(component, period):
    assert error_of(one(component, f"period = {period}")) == (
        f"t.toml: configuration 'c': {component}.period: expected a period of 0.001 to 1 s, a whole multiple of the 1 ms tick, "
        f"got {float(period) if '.' in period or 'e' in period else int(period)!r}")


@pytest.mark.parametrize("value, expected", [
    ("'sens_pos'", "expected a non-empty list of distinct names from sens_pos, desi_pos, out_vel, "
                   "following_error, tcp, io, move, frame, analog, got 'sens_pos'"),
    ("[]", "expected a non-empty list of distinct names from sens_pos, desi_pos, out_vel, following_error, "
           "tcp, io, move, frame, analog, got []"),
    ("['sens_pos', 3]", "expected column names (strings), got 3 at index 1"),
    ("['sens_pos', 'out_vell']", "unknown column 'out_vell' (did you mean 'out_vel'?); "
                                 "known: sens_pos, desi_pos, out_vel, following_error, tcp, io, move, frame, analog"),
    ("['torque']", "unknown column 'torque'; known: sens_pos, desi_pos, out_vel, following_error, tcp, io, move, frame, analog"),
    ("['out_vel', 'sens_pos', 'out_vel']", "duplicate column 'out_vel'"),
])
def test_bad_columns(value, expected):
    assert error_of(one("report", f"columns = {value}")) == f"t.toml: configuration 'c': report.columns: {expected}"


def test_mismatched_trajectory_and_initialization_periods():
    text = one("trajectory", "period = 0.005") + one("initialization", "period = 0.004")
    assert error_of(text) == (
        "t.toml: configuration 'c': trajectory.period: expected the same period as initialization.period "
        "(0.004 s; the servo interpolates both setpoint streams with one period), got 0.005")


def test_based_on_cycle():
    text = ('[configurations.a]\nbased_on = "b"\n[configurations.b]\nbased_on = "c"\n'
            '[configurations.c]\nbased_on = "a"\n')
    assert error_of(text) == "t.toml: configuration 'c': based_on cycle: a -> b -> c -> a"


def test_based_on_itself():
    assert error_of('[configurations.a]\nbased_on = "a"\n') == "t.toml: configuration 'a': based_on cycle: a -> a"


def test_based_on_cycle_reached_from_outside():
    text = ('[configurations.x]\nbased_on = "a"\n[configurations.a]\nbased_on = "b"\n'
            '[configurations.b]\nbased_on = "a"\n')
    assert error_of(text) == "t.toml: configuration 'b': based_on cycle: a -> b -> a"


def test_based_on_unknown():
    text = one("servo", "kp = 10", "standard") + '[configurations.gentle]\nbased_on = "standrad"\n'
    assert error_of(text) == ("t.toml: configuration 'gentle': based_on: no configuration 'standrad' "
                              "(did you mean 'standard'?); known: standard, gentle")


def test_based_on_not_a_string():
    assert error_of("[configurations.a]\nbased_on = 1\n") == (
        "t.toml: configuration 'a': based_on: expected the name of another configuration, got 1")


def test_unknown_default():
    assert error_of('default = "gentel"\n' + one("servo", "kp = 10", "gentle")) == (
        "t.toml: default: no configuration 'gentel' (did you mean 'gentle'?); known: gentle")
    assert error_of('default = "fast"\n' + one("servo", "kp = 10", "a") + one("servo", "kp = 10", "b")) == (
        "t.toml: default: no configuration 'fast'; known: a, b")


def test_default_not_a_string():
    assert error_of("default = 1\n" + one("servo", "kp = 10")) == (
        "t.toml: default: expected the name of a configuration, got 1")


@pytest.mark.parametrize("text", ["", "   \n# only a comment\n", 'default = "a"\n', "configurations = {}\n",
                                  "[configurations]\n"])
def test_defines_no_configurations(text):
    assert error_of(text) == "t.toml: defines no configurations (expected [configurations.NAME.COMPONENT] tables)"


def test_invalid_toml_with_line_and_column():
    text = one("servo", "kp = 40.0\nki = = 2")
    assert error_of(text) == "t.toml: invalid TOML: Invalid value (at line 3, column 6)"


def test_invalid_toml_duplicate_key():
    message = error_of(one("servo", "kp = 1\nkp = 20"))
    assert message.startswith("t.toml: invalid TOML: ") and "line 3" in message


def test_invalid_toml_too_deep():
    assert error_of("a = " + "[" * 5000 + "]" * 5000) == "t.toml: invalid TOML: nested too deeply"


def test_invalid_toml_integer_too_long():
    message = error_of(one("servo", "kp = " + "9" * 5000))
    assert message.startswith("t.toml: invalid TOML: ")


def test_first_error_in_file_order():
    text = one("servo", "kp = -1", "a") + one("servo", "ki = -1", "b")
    assert error_of(text).startswith("t.toml: configuration 'a': servo.kp:")


def test_load_error_names_the_file(tmp_path):
    path = tmp_path / "lola15.toml"
    path.write_text(one("servo", "kp = -1", "gentle"), encoding="utf-8")
    with pytest.raises(ConfigError) as info:
        load_configurations(path)
    assert str(info.value) == f"{path}: configuration 'gentle': servo.kp: expected a number 10 <= x <= 100 (1/s), got -1"


def test_load_invalid_toml(tmp_path):
    path = tmp_path / "bad.toml"
    path.write_text("[configurations.a.servo]\nkp = \n", encoding="utf-8")
    with pytest.raises(ConfigError, match=re.escape(f"{path}: invalid TOML: ") + r".*\(at line 2, column \d+\)"):
        load_configurations(path)


def test_load_missing_file(tmp_path):
    path = tmp_path / "missing.toml"
    with pytest.raises(ConfigError, match=re.escape(f"{path}: cannot read the configuration file: ") + "No such file"):
        load_configurations(path)


def test_load_directory(tmp_path):
    with pytest.raises(ConfigError, match=re.escape(f"{tmp_path}: cannot read the configuration file: ")):
        load_configurations(tmp_path)


@pytest.mark.skipif(not hasattr(os, "geteuid") or os.geteuid() == 0, reason="root reads unreadable files")
def test_load_unreadable_file(tmp_path):
    path = tmp_path / "secret.toml"
    path.write_text(one("servo", "kp = 10"), encoding="utf-8")
    path.chmod(0)
    try:
        prefix = re.escape(f"{path}: cannot read the configuration file: ")
        with pytest.raises(ConfigError, match=prefix + "Permission"):
            load_configurations(path)
    finally:
        path.chmod(0o600)


def test_load_read_error_gives_the_reason(tmp_path, monkeypatch):
    """Any OSError while reading (here a simulated permission error, which root cannot produce) is a ConfigError."""
    path = tmp_path / "lola15.toml"
    path.write_text(one("servo", "kp = 10"), encoding="utf-8")

    def refuse(self):
        raise PermissionError(13, "Permission denied", str(self))

    monkeypatch.setattr(Path, "read_bytes", refuse)
    with pytest.raises(ConfigError) as info:
        load_configurations(path)
    assert str(info.value) == f"{path}: cannot read the configuration file: Permission denied"


def test_load_path_with_nul():
    with pytest.raises(ConfigError, match="cannot read the configuration file"):
        load_configurations("bad\0name.toml")


def test_load_not_utf8(tmp_path):
    path = tmp_path / "latin1.toml"
    path.write_bytes(b"# caf\xe9\n" + one("servo", "kp = 10").encode())
    with pytest.raises(ConfigError, match=re.escape(f"{path}: not UTF-8 text (byte 5)")):
        load_configurations(path)


def test_load_accepts_str_path():
    assert load_configurations(str(SAMPLE)).names() == ["standard", "gentle"]


# ---- robustness --------------------------------------------------------------------------------

def toml_key(key: str) -> str:
    return key if re.fullmatch(r"[A-Za-z0-9_-]+", key) else toml_string(key)


def toml_string(text: str) -> str:
    """A TOML basic string: backslash, quote and control characters escaped, the rest literal."""
    return '"' + "".join(f"\\u{ord(c):04x}" if c in '"\\' or ord(c) < 0x20 or ord(c) == 0x7F else c
                         for c in text) + '"'


def toml_value(value: object) -> str:
    """A tiny TOML writer: every value inline."""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        return repr(value)
    if isinstance(value, str):
        return toml_string(value)
    if isinstance(value, list):
        return "[" + ", ".join(toml_value(v) for v in value) + "]"
    if isinstance(value, dict):
        return "{" + ", ".join(f"{toml_key(k)} = {toml_value(v)}" for k, v in value.items()) + "}"
    raise TypeError(value)


def toml_document(data: dict) -> str:
    return "".join(f"{toml_key(k)} = {toml_value(v)}\n" for k, v in data.items())


def test_tiny_toml_writer_round_trips():
    import tomllib
    data = {"default": "a b", "configurations": {"a b": {"servo": {"kp": 1.5, "ki": -3}, "x": [True, "q\n\"", 1e300]}}}
    assert tomllib.loads(toml_document(data)) == data


NAMES = ["standard", "gentle", "fast", "a", "b"]
WORDS = ["default", "configurations", "based_on", *SCHEMA, *{k for keys in SCHEMA.values() for k in keys},
         *COLUMNS, *NAMES, "kpp", "sevro"]
TEXT = st.text(alphabet=st.characters(blacklist_categories=("Cs",)), max_size=12)
KEYS = st.one_of(st.sampled_from(WORDS), TEXT)
SCALARS = st.one_of(
    st.booleans(),
    st.integers(min_value=-2 ** 63, max_value=2 ** 63 - 1),
    st.sampled_from([0, 1, 5, 200, 10_000, 10_001, 10 ** 30]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.sampled_from([0.0, 0.001, 0.005, 0.0025, 0.01, 0.02, 0.5, 1.0, 1.5, -0.005, 1e-12]),
    st.sampled_from(WORDS),
    TEXT,
)
VALUES = st.recursive(
    SCALARS,
    lambda inner: st.one_of(st.lists(inner, max_size=5), st.dictionaries(KEYS, inner, max_size=5)),
    max_leaves=25,
)


def valid_value(component: str, key: str) -> st.SearchStrategy:
    """Any value the parameter's declaration (compiler.params) accepts."""
    param = component_params(component)[key]
    if param.kind == "period":
        return st.integers(1, 1000).map(lambda n: n / 1000)
    if param.kind == "columns":
        return st.permutations(COLUMNS).flatmap(lambda cols: st.integers(1, len(cols)).map(lambda n: list(cols[:n])))
    if param.kind == "integer":
        return st.integers(int(param.low), int(param.high))
    floats = st.floats(min_value=param.low, max_value=param.high, exclude_min=param.low_open,
                       exclude_max=param.high_open)
    lowest = math.ceil(param.low)
    ints = st.integers(lowest + (1 if param.low_open and lowest == param.low else 0), int(param.high))
    return st.one_of(ints, floats)


@st.composite
def valid_settings(draw) -> dict:
    result: dict = {}
    for component, keys in SCHEMA.items():
        if draw(st.booleans()):
            chosen = draw(st.lists(st.sampled_from(sorted(keys)), unique=True))
            result[component] = {key: draw(valid_value(component, key)) for key in chosen}
    t, i = result.get("trajectory", {}), result.get("initialization", {})
    if "period" in t and "period" in i:
        i["period"] = t["period"]
    return result


@st.composite
def toml_ish(draw) -> dict:
    """Documents shaped roughly like configuration files, with random damage."""
    configs = draw(st.dictionaries(
        st.one_of(st.sampled_from(NAMES), TEXT),
        st.one_of(
            st.dictionaries(st.one_of(st.sampled_from([*SCHEMA, "based_on"]), KEYS),
                            st.one_of(st.dictionaries(KEYS, VALUES, max_size=4), st.sampled_from(NAMES), VALUES),
                            max_size=5),
            VALUES),
        min_size=1, max_size=4))
    data: dict = {"configurations": configs} if draw(st.integers(0, 9)) != 7 else {}
    if draw(st.booleans()):
        data["default"] = draw(st.one_of(st.sampled_from(NAMES), VALUES))
    if draw(st.integers(0, 9)) == 7:
        data.update(draw(st.dictionaries(KEYS, VALUES, max_size=2)))
    return data


def parses_or_config_error(text: str) -> Configurations | None:
    try:
        return parse_configurations(text, "fuzz.toml")
    except ConfigError as error:
        assert str(error).startswith("fuzz.toml: ")
        return None


@settings(max_examples=examples(400), **FUZZ)
@given(st.text(max_size=300))
@example("[configurations.a.servo]\nkp = 10")
@example("[[configurations]]\n")
@example("configurations.a = 1")
@example("[configurations.a]\nbased_on = []\n")
def test_random_text_raises_only_config_error(text):
    parses_or_config_error(text)


@settings(max_examples=examples(300), **FUZZ)
@given(st.sampled_from([SAMPLE.read_text(encoding="utf-8")]), st.integers(0, 3000), st.integers(0, 40), TEXT)
def test_mutated_sample_raises_only_config_error(sample, at, cut, insert):
    at %= len(sample) + 1
    parses_or_config_error(sample[:at] + insert + sample[at + cut:])


@settings(max_examples=examples(200), **FUZZ)
@given(toml_ish())
def test_random_documents_raise_only_config_error(data):
    configs = parses_or_config_error(toml_document(data))
    if configs is not None:
        assert configs.default in configs.by_name
        for name, config in configs.by_name.items():
            assert config.name == name
            assert validate_settings(config.settings, "again") == config.settings


@settings(max_examples=examples(300), **FUZZ)
@given(st.one_of(VALUES, st.dictionaries(st.one_of(KEYS, st.integers(), st.binary(max_size=3)),
                                         st.one_of(VALUES, st.dictionaries(KEYS, VALUES, max_size=3)), max_size=4)))
def test_validate_settings_raises_only_config_error(value):
    try:
        validate_settings(value, "net")
    except ConfigError as error:
        assert str(error).startswith("net: ")


@settings(max_examples=examples(200), **FUZZ)
@given(st.dictionaries(st.sampled_from(NAMES), valid_settings(), min_size=1), st.data())
def test_valid_configurations_load_and_read_back(configs, data):
    names = list(configs)
    default = data.draw(st.sampled_from(names))
    text = toml_document({"default": default, "configurations": configs})
    loaded = parse_configurations(text)
    assert loaded.default == default and loaded.names() == names
    for name, settings_ in configs.items():
        got = loaded[name]
        assert set(got.settings) == set(settings_)
        for component, values in settings_.items():
            for key, value in values.items():
                assert got.get(component, key) == value
                if SCHEMA[component][key].type == "number":
                    assert type(got.get(component, key)) is float


def test_the_specification_tables_are_typed_settings_read_from_the_parameter_schema():
    """spec.controller, spec.simulation and spec.safety are frozen values with one typed
    attribute per parameter of compiler.params (no dicts with defaults of their own)."""
    import dataclasses

    from compiler import params
    from compiler.spec import load_spec

    spec = load_spec(ROOT / "programs" / "lola15.spc")
    types = {"number": float, "integer": int, "choice": str}
    for section in params.SPEC_SECTIONS:
        settings = getattr(spec, section)
        accepted = params.spec_section(section)
        fields = {f.name: f.type for f in dataclasses.fields(settings)}
        assert fields == {name: types[p.kind] for name, p in accepted.items()}
        for name, param in accepted.items():
            assert isinstance(getattr(settings, name), types[param.kind])
        with pytest.raises(dataclasses.FrozenInstanceError):
            setattr(settings, next(iter(accepted)), 0)
    assert spec.controller.profile == "jerk" and spec.controller.kp == 40.0
