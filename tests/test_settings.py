"""Issue 28: the robot's settings are one object (runtime.settings), built from
compiler.params. A value two components need lives there once: a change through
apply_settings (what Robot Reconfiguration and ``irl reconfigure`` apply) or the scripting
interface is seen by every reader at once, and nothing copies it from one component into
another."""
from __future__ import annotations

import pytest

from compiler.params import COMPONENTS, component_params
from runtime.config import validate_settings
from runtime.loop.system import RobotSystem, RunOptions
from runtime.loop.scripting import call

from conftest import SPEC


def other_value(param):
    """A valid value of ``param`` other than its default (numbers: inside the range)."""
    if param.kind == "columns":
        return ["sens_pos", "out_vel"]
    if param.kind == "period":
        return 0.01 if param.default != 0.01 else 0.02
    if param.kind == "integer":
        return param.low + 1 if param.default != param.low + 1 else param.low + 2
    low, high = param.low, param.high
    value = low + 0.37 * (high - low)
    assert value != param.default
    return value


@pytest.fixture
def system():
    return RobotSystem(SPEC, RunOptions(seed=1))


def table(system):
    s = system
    return {"robot": s.robot, "servo": s.servo, "initialization": s.init, "trajectory": s.trajectory,
            "report": s.report}


def test_the_settings_are_the_table(system):
    """settings() holds every component parameter of compiler.params, no other; each
    component's scripting properties read the same values."""
    values = system.settings()
    assert list(values) == list(COMPONENTS)
    for section in COMPONENTS:
        assert list(values[section]) == list(component_params(section))
        for name, value in values[section].items():
            assert table(system)[section].get_property(name) == value
    assert values["servo"]["kp"] == SPEC.controller.kp  # the start value from [controller]


@pytest.mark.parametrize("key", [p.key for section in COMPONENTS for p in component_params(section).values()])
def test_every_setting_changes_once_and_every_reader_sees_it(system, key):
    section, name = key.split(".")
    param = component_params(section)[name]
    value = other_value(param)
    new = validate_settings({section: {name: value}}, "test")
    if name == "period" and section in ("trajectory", "initialization"):  # the two must be equal
        new = validate_settings({"trajectory": {"period": value}, "initialization": {"period": value}}, "test")
    system.apply_settings(new)
    value = new[section][name]
    assert system.settings()[section][name] == value
    component = table(system)[section]
    assert component.get_property(name) == value
    got = call(table(system), None, key)
    assert got["value"] == value
    axes = SPEC.axes
    if key == "robot.velocity_limit_scale":
        assert system.servo.max_velocity == tuple(a.max_velocity * value for a in axes)
        assert system.safety.limits.velocity_limits == tuple(a.max_velocity * value for a in axes)
        system.safety.set_referenced(None)
        assert system.safety.limits.speed_limits == tuple(a.max_velocity * value for a in axes)
        assert system.trajectory.motion.velocity_limit_scale == value
        assert [system.init.search_velocity(i) for i in range(len(axes))] == [
            min(a.search_velocity, 0.5 * value * a.max_velocity) for a in axes]
    elif key == "servo.following_error_limit":
        # the servo's fault and the safety's check: one value, the servo's section of the settings
        assert system.safety.limits.servo_settings.following_error_limit == value
        servo = system.servo
        servo.start()
        system.ports["sens_pos"].write((0.0,) * len(axes), 0.0)
        servo.hold_at((0.0,) * len(axes))
        system.ports["sens_pos"].write((value * 0.99,) + (0.0,) * (len(axes) - 1), 0.001)
        servo.update(0.001)
        assert servo.running, servo.error_message
        system.ports["sens_pos"].write((value * 1.01,) + (0.0,) * (len(axes) - 1), 0.002)
        servo.update(0.002)
        assert not servo.running and f"{value:g} deg" in servo.error_message
    elif name == "period":
        for task in system.executive.tasks:
            if task.name == section:
                assert task.period * 0.001 == pytest.approx(value)
        assert component.period == value
        if section == "trajectory":
            assert system.servo.setpoint_period == value
    elif key == "report.columns":
        assert system.report.header()[2:] == [f"{k}_{a.name}" for k in value for a in axes]


def test_a_scripting_write_is_the_settings_write(system):
    """trajectory.budget (live) written by the scripting interface is the setting itself."""
    run = call(table(system), None, "trajectory.budget = 500")
    assert callable(run)
    assert run()["value"] == 500
    assert system.settings()["trajectory"]["budget"] == 500 == system.robot_settings.trajectory.budget
