"""Issue 13: the robot cannot be driven past its limits.

One regression test (or more) for every way the arm was driven into its end stops, and
for each of the safety supervisor's checks (runtime/loop/components/safety.py), through the CLI,
the protocol (the server's request handlers, in-process) or a running system. The
``LimitWatch`` (tests/limits_watch.py) reads the simulated arm's true positions and the
commands the drives really got, every tick: nothing here trusts the runtime's own account.
"""
from __future__ import annotations

import json
import math

import pytest

from compiler.driver import compile_source
from compiler.objcode import encode
from compiler.spec import SpecError, parse_spec
from limits_watch import IdleHost, LimitWatch, at_rest_and_safe, run_cycle
from runtime.wire import protocol
from runtime.cli.main import main
from runtime.loop.components.safety import CATEGORIES
from runtime.config import ConfigError, parse_configurations
from runtime.wire.protocol import ProtocolError
from runtime.server.server import ServeOptions, Server
from runtime.loop.supervisor import INITIALIZE, MOVE, StateFile
from runtime.loop.system import RobotSystem, RunOptions

from conftest import SPEC_PATH, SPEC, TEST_IRL
AXES = [a.name for a in SPEC.axes]
#: How far beyond a software limit an axis may come when the safety stops it (docs/safety.md).
STOP_TOLERANCE = 0.5


def run_cli(*argv) -> tuple[int, str, str]:
    import io

    from runtime.cli.main import Environment

    out, err = io.StringIO(), io.StringIO()
    code = main([str(a) for a in argv], Environment(stdout=out, stderr=err))
    assert code != 70 and "Traceback" not in err.getvalue(), err.getvalue()
    return code, out.getvalue(), err.getvalue()


def program(body: str, decls: str = "", name: str = "safety"):
    text = f'program {name};\nsystem_specification "{SPEC_PATH}";\n{decls}seq\n{body}endseq\nendprogram;\n'
    result = compile_source(text, f"{name}.irl", SPEC_PATH)
    assert result.ok, result.diagnostics
    return result.program


PAPER = program(TEST_IRL.read_text(encoding="utf-8").split("seq", 1)[1].rsplit("endseq", 1)[0])
LONG = program("  move ptp joint(mainjoint(40, 10, -10, 0, 30, 0)) speed_ptp := 0.1 acc_ptp := 0.2;\n"
               "  move ptp joint(mainjoint(-40, -10, 10, 0, -30, 0)) speed_ptp := 0.1 acc_ptp := 0.2;\n")
SHORT = program("  move ptp joint(mainjoint(5, 0, 0, 0, 0, 0)) speed_ptp := 0.5 acc_ptp := 0.5;\n")


def fresh(seed: int = 0, **options) -> tuple[RobotSystem, LimitWatch]:
    system = RobotSystem(SPEC, RunOptions(seed=seed, **options))
    return system, LimitWatch(system)


def run_to_end(system: RobotSystem, prog, ticks: int = 400_000, during=None) -> dict:
    return run_cycle(system, prog, ticks, during)


def run_until(system: RobotSystem, condition, ticks: int = 400_000) -> None:
    for _ in range(ticks):
        if condition():
            return
        system.executive.step()
    raise AssertionError("the condition never came")


def into_move(system: RobotSystem, seconds: float) -> None:
    """Step until the program has been in Move Robot for ``seconds``."""
    run_until(system, lambda: system.supervisor.fsm.state == MOVE)
    t0 = system.clock.now()
    run_until(system, lambda: system.clock.now() >= t0 + seconds)
    assert system.supervisor.fsm.state == MOVE


def category(summary: dict) -> int | None:
    return summary["stop"]["category"] if summary["stop"] else None


def safe_end(system: RobotSystem, watch: LimitWatch, summary: dict | None = None) -> None:
    """What every cycle must end with, whatever happened in it."""
    assert at_rest_and_safe(system), "not at rest with brakes applied and torque off"
    assert not watch.at_end_stop
    assert watch.beyond <= STOP_TOLERANCE, (watch.beyond, watch.worst)
    assert watch.velocity_ratio <= 1.0 + 1e-9, (watch.velocity_ratio, watch.worst)
    assert watch.acceleration_ratio <= SPEC.safety.acceleration_factor + 1e-9, (watch.acceleration_ratio,
                                                                                     watch.worst)


# ---- 1. a failed homing is never remembered as done ------------------------------------------------

@pytest.mark.parametrize("how", ["estop", "fault", "abort"])
def test_a_homing_that_does_not_complete_is_not_remembered(how):
    system, watch = fresh()
    system.begin(PAPER, None)
    run_until(system, lambda: "Find Index" in system.supervisor.fsm.path())
    if how == "estop":
        system.emergency_stop()
    elif how == "fault":
        system.backend.inject("drive_dead", 1)
    else:
        system.supervisor.request_stop("aborted by the operator")
    run_until(system, lambda: system.supervisor.done)
    summary = system.finish()
    assert summary["fault"] and INITIALIZE in summary["fault"]
    assert not system.memory.initialized
    assert system.memory.initialization_why.startswith("not initialized:")
    safe_end(system, watch)
    system.backend.clear_faults()
    watch.reset()
    # the calibration of that cycle was never confirmed (no homing completed): measured again
    assert not system.memory.calibrated and "measured in the cycle" in system.memory.calibration_why
    again = run_to_end(system, PAPER)  # calibrates and homes again, and moves where the program says
    assert [s["name"] for s in again["states"]] == ["Start Robot", "Calibrate Offsets", INITIALIZE, MOVE,
                                                    "Stop Robot"]
    assert again["fault"] is None
    assert again["final_position"] == pytest.approx([45, -45, 45, 0, 0, 0], abs=0.01)
    assert system.memory.initialized and system.memory.initialization_why.startswith("initialized: homing completed")
    safe_end(system, watch)


def test_any_cycle_that_ends_early_forgets_the_homing_and_a_completed_one_keeps_it():
    system, watch = fresh()
    assert run_to_end(system, SHORT)["fault"] is None and system.memory.initialized
    second = run_to_end(system, SHORT)
    assert INITIALIZE not in [s["name"] for s in second["states"]]  # kept: the cycle ended normally
    system.begin(LONG, None)
    into_move(system, 2.0)
    system.emergency_stop()
    run_until(system, lambda: system.supervisor.done)
    summary = system.finish()
    assert category(summary) == CATEGORIES["emergency stop"][0] == 1
    assert not system.memory.initialized and "ended early" in system.memory.initialization_why
    safe_end(system, watch)


def test_status_says_why_over_the_protocol(tmp_path):
    server = Server(SPEC, ServeOptions(sim_clock=True, state_dir=tmp_path / "state", loop_process=False))
    status = server.op_status({})
    assert status["initialized"] is False and "no homing sequence has completed" in status["initialization"]
    assert status["calibration"].startswith("not calibrated")


# ---- 2. the servo stopped while a move runs: the command watchdog -----------------------------------

def test_servo_stop_while_moving_is_refused_over_the_network_and_caught_by_the_watchdog_in_process(tmp_path):
    server = Server(SPEC, ServeOptions(sim_clock=True, state_dir=tmp_path / "state", loop_process=False))
    server.op_submit({"object": encode(LONG)})
    while not (server.jobs.current is not None and server.system.supervisor.fsm.state == MOVE):
        server.turn(idle_wait=False)
    for text in ("servo.stop()", "report.stop()", "robot.release_brakes()", "trajectory.stop()", "servo.hold()"):
        with pytest.raises(ProtocolError) as refused:
            server.request("call", {"text": text})
        assert refused.value.code == "refused" and "could move the robot" in refused.value.message \
            or "Start Robot" in refused.value.message, refused.value.message
    assert server.system.servo.running
    # the servo stopped anyway (a bug, a stall): the safety stops the robot within two ticks
    system = server.system
    system.servo.stop()
    for _ in range(5):
        server.turn(idle_wait=False)
    assert system.safety.stopping and "no fresh command from the servo" in system.safety.fault
    while server.jobs.current is not None:
        server.turn(idle_wait=False)
    job = server.jobs[1]
    assert job.state == "faulted" and "watchdog" not in job.fault and "servo" in job.fault
    assert job.summary["stop"]["category"] == CATEGORIES["watchdog"][0]
    assert at_rest_and_safe(system)


# ---- 3. scripting writes: ranges, safety relevance, lifecycle ------------------------------------------

@pytest.mark.parametrize("text, code, words", [
    ("robot.velocity_limit_scale = -1", "refused", "safety-relevant"),
    ("robot.velocity_limit_scale = 0.5", "refused", "safety-relevant"),
    ("servo.kp = -40", "refused", "safety-relevant"),
    ("servo.kp = 1e9", "refused", "safety-relevant"),
    ("servo.following_error_limit = 1e308", "refused", "safety-relevant"),
    ("initialization.home_speed = 1", "refused", "safety-relevant"),
    ("trajectory.period = 0.002", "refused", "irl reconfigure"),
    ("trajectory.budget = 0", "bad_request", "trajectory.budget: expected an integer 1 <= x <= 10000"),
    ("trajectory.budget = 1000000000000", "bad_request", "got 1000000000000"),
    ("trajectory.budget = 99999999999999999999999", "bad_request", "expected an integer 1 <= x <= 10000"),
    ("trajectory.budget = 2.5", "bad_request", "expected an integer"),
    ('trajectory.budget = "nan"', "bad_request", "expected an integer"),
    ('fsm.mode = "reactive"', "script_error", "read-only"),
])
def test_scripting_writes_are_validated_and_safety_parameters_refused(tmp_path, text, code, words):
    server = Server(SPEC, ServeOptions(sim_clock=True, state_dir=tmp_path / "state", loop_process=False))
    before = server.system.settings()
    with pytest.raises(ProtocolError) as refused:
        server.request("call", {"text": text})
    assert refused.value.code == code and words in refused.value.message, refused.value.message
    assert server.system.settings() == before  # nothing stored
    assert server.system.supervisor.fsm.mode == "automatic"


def test_a_live_parameter_is_written_and_lifecycle_operations_run_only_while_idle(tmp_path):
    server = Server(SPEC, ServeOptions(sim_clock=True, state_dir=tmp_path / "state", loop_process=False))
    assert server.request("call", {"text": "trajectory.budget = 500"})["value"] == 500
    assert server.system.robot_settings.trajectory.budget == 500
    assert server.request("call", {"text": "report.stop()"})["value"] is False  # idle: allowed (nothing to stop)
    with pytest.raises(ProtocolError, match="released only by Start Robot"):
        server.request("call", {"text": "robot.release_brakes()"})
    assert server.system.backend.brakes_applied()


# ---- 4. the encoder frozen during homing --------------------------------------------------------------

@pytest.mark.parametrize("axis", ["A2", "A3", "A4"])
def test_a_frozen_encoder_during_homing_stops_the_robot_before_it_moves_far(axis):
    system, watch = fresh(faults=[("encoder_frozen", AXES.index(axis))])
    summary = run_to_end(system, PAPER)
    assert summary["fault"] and axis in summary["fault"] and "encoder" in summary["fault"]
    assert category(summary) == CATEGORIES["encoder"][0] == 0
    safe_end(system, watch, summary)
    # the axis was stopped after a tenth of a degree of commanded travel, not at an end stop
    i = AXES.index(axis)
    low, high = system.backend.end_stops[i]
    assert low + 5 < system.backend.true_positions[i] < high - 5


def test_a_frozen_encoder_through_the_cli():
    code, out, err = run_cli("run", TEST_IRL, "--inject", "encoder_frozen:A2", "--json")
    assert code == 1
    summary = json.loads(out)
    assert "A2" in summary["fault"] and summary["stop"]["category"] == 0
    code, out, err = run_cli("run", TEST_IRL, "--inject", "drive_dead:A3")
    assert code == 1 and "stopped: category 0" in out and "A3" in out


# ---- 5. the specification's and the configurations' values are validated -----------------------------

@pytest.mark.parametrize("line, words", [
    ("following_error_limit = nan", "controller.following_error_limit: expected a number 0.1 <= x <= 10"),
    ("following_error_limit = inf", "controller.following_error_limit: expected a number 0.1 <= x <= 10"),
    ("following_error_limit = 1e308", "controller.following_error_limit: expected a number 0.1 <= x <= 10"),
    ("servo_miss_limit = inf", "controller.servo_miss_limit: expected an integer"),
    ('servo_miss_policy = "bogus"', 'controller.servo_miss_policy: expected one of "hard", "firm", "soft"'),
    ("servo_miss_limit = 5000", "controller.servo_miss_limit: expected fewer misses than the window"),
    ("kp = 1e9", "controller.kp: expected a number 10 <= x <= 100 (1/s)"),
    ("folowing_error_limit = 0.5", "controller.folowing_error_limit: unknown key (did you mean "
                                   "'following_error_limit'?)"),
])
def test_controller_values_are_validated_by_check_and_run(tmp_path, line, words):
    text = SPEC_PATH.read_text(encoding="utf-8").replace("[controller]\n", f"[controller]\n{line}\n", 1)
    if line.startswith(("following_error_limit", "servo_miss_limit", "servo_miss_policy", "kp")):
        key = line.split("=")[0].strip()  # replace the spec's own line for this key
        lines = text.split("\n")
        first = next(i for i, raw in enumerate(lines) if raw.startswith(key + " ") and raw != line)
        del lines[first]
        text = "\n".join(lines)
    (tmp_path / "lola15.spc").write_text(text, encoding="utf-8")
    (tmp_path / "test.irl").write_text(TEST_IRL.read_text(encoding="utf-8"), encoding="utf-8")
    for command in ("check", "run"):
        code, out, err = run_cli(command, tmp_path / "test.irl")
        assert code == 1 and words in err, (command, err)


@pytest.mark.parametrize("table, line, words", [
    ("safety", "standstill_tolerance = 0", "safety.standstill_tolerance: expected an integer 1 <= x <= 10000"),
    ("safety", "acceleration_factor = nan", "safety.acceleration_factor: expected a number 1 <= x <= 10"),
    ("safety", "max_drive_drift = -1", "safety.max_drive_drift"),
    ("simulation", "end_stop_margin = 0", "simulation.end_stop_margin: expected a number 0.1 <= x <= 90"),
    ("simulation", "brake_time = inf", "simulation.brake_time"),
])
def test_safety_and_simulation_tables_are_validated(table, line, words):
    text = SPEC_PATH.read_text(encoding="utf-8") + f"\n[{table}]\n{line}\n"
    if table == "simulation":
        text = text.replace("[simulation]\n", "[simulation_old]\n", 1).replace("[simulation_old]", "# ", 1)
        text = text.replace("drive_time_constant = 0.005", "#", 1).replace("max_drive_offset = 0.5", "#", 1)
        text = text.replace("park_spread = 3.0", "#", 1)
    with pytest.raises(SpecError) as error:
        parse_spec(text, "x.spc")
    assert words in str(error.value), str(error.value)


@pytest.mark.parametrize("settings, words", [
    ("kp = 1e9", "servo.kp: expected a number 10 <= x <= 100 (1/s), got 1000000000.0"),
    ("following_error_limit = 1e299", "servo.following_error_limit: expected a number 0.1 <= x <= 10"),
    ("following_error_limit = nan", "servo.following_error_limit: expected a number 0.1 <= x <= 10"),
])
def test_configurations_refuse_out_of_range_values(settings, words):
    with pytest.raises(ConfigError) as error:
        parse_configurations(f"[configurations.c.servo]\n{settings}\n", "t.toml")
    assert words in str(error.value), str(error.value)


# ---- 6. a stop never loses the report; the report shows the robot at rest -------------------------------

def test_an_estop_mid_move_ramps_every_axis_down_within_its_limits_and_the_report_shows_rest(tmp_path):
    system, watch = fresh(report=tmp_path / "r.csv")
    system.begin(LONG, tmp_path / "r.csv")
    run_until(system, lambda: system.supervisor.fsm.state == MOVE and max(map(abs, system.trajectory.motion.velocities))
              > 10)
    moving = system.ports["drive_cmd"].value
    system.emergency_stop()
    run_until(system, lambda: system.supervisor.done)
    summary = system.finish()
    assert summary["stop"]["category"] == 1 and "emergency stop" in summary["fault"]
    # the safety's own ramp: at each axis's max_acceleration, not beyond
    assert watch.acceleration_ratio <= 1.0 + 1e-9, watch.worst
    safe_end(system, watch, summary)
    rows = (tmp_path / "r.csv").read_text(encoding="utf-8").splitlines()
    header = rows[0].split(",")
    last = dict(zip(header, rows[-1].split(",")))
    assert last["state"] == "Stop Robot"
    assert all(float(last[f"out_vel_{n}"]) == 0.0 for n in AXES)
    assert max(map(abs, moving)) > 10


# ---- the safety supervisor's checks, each made to fire -----------------------------------------------

def test_a_runaway_servo_gain_is_an_acceleration_fault_not_a_runaway():
    system, watch = fresh()
    run_to_end(system, SHORT)
    system.begin(LONG, None)
    run_until(system, lambda: system.supervisor.fsm.state == MOVE)
    system.robot_settings.servo.kp = 1e9  # past every check the configuration has (a servo bug)
    run_until(system, lambda: system.supervisor.done)
    summary = system.finish()
    assert "safety:" in summary["fault"] and "command changes at" in summary["fault"]
    assert category(summary) == CATEGORIES["acceleration"][0]
    safe_end(system, watch, summary)


def test_positive_feedback_with_the_following_error_switched_off_stops_before_the_limits():
    system, watch = fresh()
    run_to_end(system, SHORT)
    system.begin(LONG, None)
    run_until(system, lambda: system.supervisor.fsm.state == MOVE)
    system.robot_settings.servo.kp = -40.0  # past every check (written to the settings' section directly)
    system.robot_settings.servo.following_error_limit = 1e308  # the servo's and the safety's: one value
    run_until(system, lambda: system.supervisor.done)
    summary = system.finish()
    assert "safety:" in summary["fault"], summary["fault"]
    safe_end(system, watch, summary)


def test_a_move_planned_beyond_the_limit_is_stopped_before_the_limit(tmp_path):
    """A planner bug: the program's target lies 20 deg beyond A5's limit and the planner
    lets it through; the safety stops the axis before the limit (it looks at where the axis
    would come to rest at full deceleration, not at where it is)."""
    import dataclasses

    text = SPEC_PATH.read_text(encoding="utf-8").replace("max = 120.0", "max = 150.0", 1)
    (tmp_path / "wide.spc").write_text(text, encoding="utf-8")
    source = (f'program beyond;\nsystem_specification "{tmp_path / "wide.spc"}";\nseq\n'
              '  move ptp joint(mainjoint(0, 0, 0, 0, 140, 0)) speed_ptp := 1 acc_ptp := 1;\nendseq\nendprogram;\n')
    result = compile_source(source, "beyond.irl", tmp_path / "wide.spc")
    assert result.ok, result.diagnostics
    system, watch = fresh()
    run_to_end(system, SHORT)
    tg = system.trajectory
    tg.planner.axes = tuple(dataclasses.replace(a, max=150.0) if a.name == "A5" else a for a in SPEC.axes)
    summary = run_to_end(system, result.program)
    a5 = SPEC.axes[4]
    assert "would come to rest" in summary["fault"] and "A5" in summary["fault"], summary["fault"]
    assert category(summary) == CATEGORIES["position limit"][0]
    safe_end(system, watch, summary)
    assert system.backend.true_positions[4] <= a5.max + STOP_TOLERANCE


def test_an_axis_that_moves_while_paused_is_a_standstill_fault():
    system, watch = fresh()
    run_to_end(system, SHORT)
    system.begin(LONG, None)
    into_move(system, 5)
    assert system.trajectory.pause()
    run_until(system, lambda: all(system.safety.in_position))  # at rest, in position: standstill watched
    backend = system.backend
    backend.set_drive_offset(2, backend.drive_offsets[2] + 20.0)  # the drive of A3 drifts hard
    run_until(system, lambda: system.supervisor.done)
    summary = system.finish()
    assert "A3" in summary["fault"] and "at rest" in summary["fault"], summary["fault"]
    assert category(summary) == CATEGORIES["standstill"][0] == 0
    safe_end(system, watch, summary)


def test_an_encoder_that_counts_the_wrong_way_is_a_fault():
    system, watch = fresh()
    run_to_end(system, SHORT)
    backend = system.backend
    read_counts = backend.read_counts

    def reversed_a1():  # A1's encoder wired backwards from now on
        counts = list(read_counts())
        counts[0] = 2 * reversed_a1.at - counts[0]
        return tuple(counts)
    reversed_a1.at = read_counts()[0]
    system.begin(LONG, None)
    run_until(system, lambda: system.supervisor.fsm.state == MOVE)
    reversed_a1.at = read_counts()[0]
    backend.read_counts = reversed_a1
    run_until(system, lambda: system.supervisor.done)
    summary = system.finish()
    assert "A1" in summary["fault"] and "safety:" in summary["fault"], summary["fault"]
    assert category(summary) in (0, 1)
    safe_end(system, watch, summary)


def test_a_stop_on_the_path_that_never_ends_is_taken_over():
    system, watch = fresh()
    run_to_end(system, SHORT)
    system.begin(LONG, None)
    into_move(system, 5)
    tg = system.trajectory
    tg.pause()
    tg.motion.at_rest = lambda: False  # a planner bug: it never tells that its stop reached rest
    run_until(system, lambda: system.supervisor.done)
    summary = system.finish()
    assert "did not reach rest" in summary["fault"]
    assert category(summary) == CATEGORIES["stop overdue"][0]
    safe_end(system, watch, summary)


def test_the_following_error_is_caught_even_when_the_servo_does_not_fault():
    system, watch = fresh()
    run_to_end(system, SHORT)
    system.servo._following_error_fault = lambda out: None  # the servo's own check broken
    system.begin(LONG, None)
    into_move(system, 5)
    backend = system.backend
    backend.set_drive_offset(1, backend.drive_offsets[1] - 80.0)  # A2 dragged away (a failing drive)
    run_until(system, lambda: system.supervisor.done)
    summary = system.finish()
    assert "safety:" in summary["fault"], summary["fault"]
    safe_end(system, watch, summary)


def test_the_drives_never_apply_a_command_the_safety_did_not_pass():
    system, watch = fresh()
    run_to_end(system, SHORT)
    system.begin(LONG, None)
    into_move(system, 2.0)
    system.safety.stop()  # the safety supervisor itself stopped (lifecycle): nothing is passed on
    run_until(system, lambda: system.supervisor.done)
    summary = system.finish()
    assert "no command from the safety supervisor" in summary["fault"]
    assert at_rest_and_safe(system)


@pytest.mark.parametrize("seed", [0, 2])
def test_a_long_pause_holds_without_a_false_alarm(seed):
    """Holding still for minutes (the servo's integral against the drive's residual drift,
    an axis resting between two counts) trips neither standstill nor plausibility. (Two
    seeds, paused at two places of the move; a third, in between, added no case and 6 s
    of CPU to the suite.)"""
    system, watch = fresh(seed)
    system.begin(LONG, None)
    into_move(system, 16 - 12 + seed)
    system.trajectory.pause()
    for _ in range(180_000):  # three minutes
        system.executive.step()
    assert system.safety.fault is None and system.supervisor.fault is None
    system.trajectory.resume()
    run_until(system, lambda: system.supervisor.done)
    summary = system.finish()
    assert summary["fault"] is None
    safe_end(system, watch, summary)


def test_reduced_speed_from_a_configuration_is_planned_and_enforced():
    system, watch = fresh()
    settings = {"robot": {"velocity_limit_scale": 0.25}}
    system.apply_settings(settings)
    full = run_to_end(RobotSystem(SPEC, RunOptions()), SHORT)
    reduced = run_to_end(system, SHORT)
    assert reduced["fault"] is None
    assert watch.velocity_ratio <= 1.0 + 1e-9  # relative to 0.25 x max_velocity
    assert reduced["moves"][0]["actual_duration"] > 1.5 * full["moves"][0]["actual_duration"]


# ---- the calibration file: checked on load, written off the loop ------------------------------------

def test_a_bad_calibration_file_is_not_used_and_status_says_why(tmp_path):
    state = tmp_path / "state"
    system, watch = fresh(state_dir=state)
    assert run_to_end(system, SHORT)["fault"] is None
    path = state / "calibration.json"
    good = json.loads(path.read_text(encoding="utf-8"))
    assert good["spec_hash"] == SPEC.hash and good["backend"] == "sim-seed-0" and good["format"] == 2
    limit = SPEC.safety.max_drive_drift
    drift = [1.0] * len(AXES)
    files = StateFile(state, {"robot": SPEC.name, "spec_hash": SPEC.hash, "backend": "sim-seed-0"},
                      (limit,) * len(AXES))
    cases = [
        (dict(good, compensation=[156.0] + good["compensation"][1:]), "outside the allowed drift"),
        (dict(good, compensation=[math.inf] * len(AXES)), None),  # not JSON-able as such: see below
        (dict(good, compensation=drift[:3]), f"does not hold {len(AXES)} values"),
        (dict(good, spec_hash="0" * 64), "another specification"),
        (dict(good, backend="sim-seed-9"), "another robot backend"),
        (dict(good, format=1), "not a calibration file of format 2"),
    ]
    for data, why in cases:
        text = json.dumps(data)  # infinity is written as Infinity, which json reads back
        path.write_text(text, encoding="utf-8")
        values, reason = files.load()
        assert values is None, data
        if why:
            assert why in reason, reason
    path.write_text(json.dumps(dict(good, compensation=[156.0] * len(AXES))), encoding="utf-8")
    again, _ = fresh(state_dir=state)
    summary = run_to_end(again, SHORT)
    assert "Calibrate Offsets" in [s["name"] for s in summary["states"]]  # measured again, not used
    assert again.memory.calibration_why.startswith("calibrated: measured")


def test_a_drive_that_drifts_beyond_the_limit_fails_calibration():
    system, watch = fresh()
    system.backend.set_drive_offset(0, 5.0)  # beyond [safety] max_drive_drift (2 deg/s)
    summary = run_to_end(system, SHORT)
    assert "Calibrate Offsets" in summary["fault"] and "drifts" in summary["fault"] and "A1" in summary["fault"]
    assert not system.memory.calibrated
    assert at_rest_and_safe(system)


# ---- 5. no program can stall the loop or exhaust memory ------------------------------------------------

def test_a_string_that_grows_without_bound_stops_the_program_at_its_line():
    prog = program('  s := "x";\n  while true do\n    s := s + s;\n  endwhile;\n', 'var s : string;\n')
    system, watch = fresh()
    summary = run_to_end(system, prog)
    assert summary["fault"] and "line 7" in summary["fault"] and "string too long" in summary["fault"]
    assert at_rest_and_safe(system)


def test_a_forged_object_cannot_allocate_without_bound():
    from compiler.objcode import OP, MAX_ARRAY_ELEMENTS, MAX_STRING_LENGTH, ObjectCodeError, load
    from runtime.loop.vm import ERROR, VM

    forged = program("  print 1;\n")
    code = ((OP.CONST, 0), (OP.MAKE_ARRAY, MAX_ARRAY_ELEMENTS), (OP.MAKE_ARRAY, MAX_ARRAY_ELEMENTS),
            (OP.STORE_GLOBAL, 0), (OP.END,))
    import dataclasses

    nested = dataclasses.replace(forged, code=code, constants=(0.0,), globals=("a",),
                                 lines=tuple((i, 1, 1) for i in range(len(code))))

    vm = VM(nested, IdleHost())
    vm.step()
    assert vm.status is ERROR and "larger than" in vm.error.message
    too_long = dataclasses.replace(forged, constants=("x" * (MAX_STRING_LENGTH + 1),))
    with pytest.raises(ObjectCodeError, match="at most 10000"):
        load(encode(too_long), None)


def test_the_interpreter_time_per_update_is_bounded_on_the_wall_clock():
    from runtime.loop.vm import VM

    prog = program("  while true do\n    i := i + 1;\n  endwhile;\n", "var i : integer;\n")

    import time

    vm = VM(prog, IdleHost(), budget=10_000)
    start = time.perf_counter()
    vm.step(deadline=start)  # the deadline is already over: one slice, then the step ends
    assert vm.instructions <= 64
    vm.step()  # no deadline (the simulated clock): the whole budget
    assert vm.instructions >= 10_000


def test_protocol_requests_with_huge_values_are_answered_not_crashed(tmp_path):
    server = Server(SPEC, ServeOptions(sim_clock=True, state_dir=tmp_path / "state", loop_process=False))
    for request in ({"text": "trajectory.budget = " + "9" * 4000}, {"text": "servo.kp = 1" + "0" * 400 + ".0"}):
        with pytest.raises(ProtocolError) as error:
            server.request("call", request)
        assert error.value.code in ("bad_request", "refused", "script_error")
    assert protocol.decode_reply(protocol.ok(1, {"x": 1}))["ok"]


def test_a_string_literal_longer_than_the_limit_is_a_diagnostic(tmp_path):
    from compiler.objcode import MAX_STRING_LENGTH

    path = tmp_path / "long.irl"
    path.write_text(f'program p;\nsystem_specification "{SPEC_PATH}";\nvar s : string;\nseq\n'
                    f'  s := "{"x" * (MAX_STRING_LENGTH + 1)}";\nendseq\nendprogram;\n', encoding="utf-8")
    code, out, err = run_cli("check", path)
    assert code == 1 and f"long.irl:5:8: error: a string of {MAX_STRING_LENGTH + 1} characters is too long" in err


# ---- the same, through the CLI and the protocol ------------------------------------------------------

def test_an_estop_during_homing_then_the_next_program_homes_again_over_the_protocol(tmp_path):
    server = Server(SPEC, ServeOptions(sim_clock=True, state_dir=tmp_path / "state", loop_process=False))
    watch = LimitWatch(server.system)
    first = server.op_submit({"object": encode(SHORT)})["program"]
    while not (server.jobs.current is not None and "Find Index" in server.system.supervisor.fsm.path()):
        server.turn(idle_wait=False)
    server.link.commands.append((b"c", 1, server.op_estop({})))
    while server.jobs.current is not None:
        server.turn(idle_wait=False)
    assert server.jobs[first].state == "aborted"
    status = server.op_status({})
    assert status["initialized"] is False and "ended early" in status["initialization"], status
    assert at_rest_and_safe(server.system)
    second = server.op_submit({"object": encode(SHORT)})["program"]
    while server.jobs[second].state in ("queued", "running"):
        server.turn(idle_wait=False)
    job = server.jobs[second]
    assert job.state == "completed", job.fault
    assert INITIALIZE in [s["name"] for s in job.summary["states"]]
    assert server.op_status({})["initialized"] is True
    assert not watch.at_end_stop and watch.beyond == 0.0


def test_a_growing_string_and_a_forged_array_through_irl_run(tmp_path):
    import dataclasses

    from compiler.objcode import MAX_ARRAY_ELEMENTS, OP

    grow = tmp_path / "grow.irl"
    grow.write_text(f'program grow;\nsystem_specification "{SPEC_PATH}";\nvar s : string;\nseq\n  s := "x";\n'
                    '  while true do\n    s := s + s;\n  endwhile;\nendseq\nendprogram;\n', encoding="utf-8")
    code, out, err = run_cli("run", grow)
    assert code == 1 and "line 7: string too long" in out, out
    base = program("  print 1;\n", "var a : array[1..2] of array[1..2] of real;\n")  # well typed: the size is the fault
    code_ = ((OP.CONST, 0), (OP.MAKE_ARRAY, MAX_ARRAY_ELEMENTS), (OP.MAKE_ARRAY, MAX_ARRAY_ELEMENTS),
             (OP.STORE_GLOBAL, 0), (OP.END,))
    forged = dataclasses.replace(base, code=code_, constants=(0.0,),
                                 lines=tuple((i, 5, 3) for i in range(len(code_))))
    path = tmp_path / "forged.irlo"
    path.write_bytes(encode(forged))
    code, out, err = run_cli("run", path, "--spec", SPEC_PATH)
    assert code == 1 and "larger than 100000 elements" in out, out + err


def test_an_out_of_range_configuration_is_refused_by_irl_serve(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[configurations.fast.servo]\nkp = 1e9\nfollowing_error_limit = 1e299\n", encoding="utf-8")
    code, out, err = run_cli("serve", "--spec", SPEC_PATH, "--config", bad, "--sim-clock",
                             "--endpoint", "tcp://127.0.0.1:1", "--telemetry", "tcp://127.0.0.1:2")
    assert code == 2 and "servo.kp: expected a number 10 <= x <= 100 (1/s), got 1000000000.0" in err, err


@pytest.mark.parametrize("fault", ["encoder_frozen", "drive_dead"])
def test_a_calibration_measured_with_a_broken_axis_is_never_kept(tmp_path, fault):
    """A frozen encoder or a dead drive measures a plausible drift of zero: such a
    calibration is confirmed only by a homing that completes, never saved before."""
    state = tmp_path / "state"
    system, watch = fresh(state_dir=state, faults=[(fault, 3)])
    summary = run_to_end(system, PAPER)
    assert summary["fault"] and "A4" in summary["fault"]
    assert not system.memory.calibrated and not (state / "calibration.json").exists()
    system.backend.clear_faults()  # repaired: the next program calibrates again and completes
    summary = run_to_end(system, PAPER)
    assert summary["fault"] is None, summary["fault"]
    assert "Calibrate Offsets" in [s["name"] for s in summary["states"]]
    assert (state / "calibration.json").exists() and system.memory.calibrated
    safe_end(system, watch)


def test_homing_again_after_a_stop_mid_search_searches_towards_the_sensor():
    """An emergency stop during A1's sensor search leaves it some degrees from where it was
    powered up; the next homing must search from where it is now, not from the power-up
    position taken as home (it used to run the wrong way, into the other end stop)."""
    system, watch = fresh()
    system.begin(PAPER, None)
    run_until(system, lambda: system.init.step_name == "sensor A1")
    t0 = system.clock.now()
    run_until(system, lambda: system.clock.now() >= t0 + 1.1)
    system.emergency_stop()
    run_until(system, lambda: system.supervisor.done)
    system.finish()
    summary = run_to_end(system, PAPER)
    assert summary["fault"] is None, summary["fault"]
    assert summary["final_position"] == pytest.approx([45, -45, 45, 0, 0, 0], abs=0.01)
    safe_end(system, watch)


def test_a_dead_homing_sensor_is_searched_for_a_bounded_distance_not_to_the_end_stop():
    system, watch = fresh(faults=[("sensor_dead", 1)])
    summary = run_to_end(system, PAPER)
    assert "homing sensor of A2 not found within" in summary["fault"], summary["fault"]
    safe_end(system, watch)
    # the sensor is at -5: searched down to about -15.5, then back up once over that and 20 more
    assert -20 < system.backend.true_positions[1] < 25, system.backend.true_positions[1]


FULL_SPEED = program("  move ptp joint(mainjoint(60, -10, 50, 40, 30, 90)) speed_ptp := 1 acc_ptp := 1 approx := 1;\n"
                     "  move ptp joint(mainjoint(-60, -40, 20, -40, 80, -90)) speed_ptp := 1 acc_ptp := 1;\n")


@pytest.mark.parametrize("when, percent", [(0.12, 1), (0.4, 50), (0.6, 1), (0.72, 50)])
def test_a_change_of_override_at_full_acceleration_keeps_the_limits(when, percent):
    """The rate of trajectory time adds (rate)' x v to each axis's acceleration: it changes
    only as fast as the path's own acceleration leaves room for (it used to reach twice the
    limit at a full-acceleration move, and the safety stopped a healthy robot)."""
    system, watch = fresh()
    run_to_end(system, SHORT)
    watch.reset()
    system.begin(FULL_SPEED, None)
    into_move(system, when)
    system.trajectory.override = percent
    for _ in range(300):
        system.executive.step()
    system.trajectory.override = 100
    run_until(system, lambda: system.supervisor.done)
    summary = system.finish()
    assert summary["fault"] is None, summary["fault"]
    assert watch.acceleration_ratio <= 1.25, watch.worst
    safe_end(system, watch)


@pytest.mark.parametrize("when", [0.5, 0.9, 1.1])
def test_a_pause_inside_a_full_speed_blend_and_a_quick_resume_keep_the_limits(when):
    system, watch = fresh()
    run_to_end(system, SHORT)
    watch.reset()
    system.begin(FULL_SPEED, None)
    into_move(system, when)
    system.trajectory.pause()
    for _ in range(150):  # resumed before it came to rest
        system.executive.step()
    system.trajectory.resume()
    run_until(system, lambda: system.supervisor.done)
    summary = system.finish()
    assert summary["fault"] is None, summary["fault"]
    assert watch.acceleration_ratio <= 1.25, watch.worst
    safe_end(system, watch)


def test_every_stop_names_its_cause_in_categories():
    """A stop's category comes from CATEGORIES alone: every call of ``stop_robot`` (and of
    the safety's own ``_violation``, which passes its cause on) in the runtime names a cause
    of the table (a string), never a category number (issue 28)."""
    import ast
    from pathlib import Path

    from runtime.loop.components import safety

    root = Path(__file__).resolve().parents[1] / "runtime"
    calls = []
    for path in sorted(root.rglob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Call) and getattr(node.func, "attr", None) in ("stop_robot", "_violation"):
                where = f"{path.relative_to(root.parent)}:{node.lineno}"
                cause = node.args[0] if node.args else None
                if isinstance(cause, ast.Name) and cause.id == "cause" and node.func.attr == "stop_robot":
                    continue  # _violation(cause, ...) passing its own argument on
                if isinstance(cause, ast.Subscript) and getattr(cause.value, "id", None) == "_KINDS":
                    continue  # a kernel's verdict: _KINDS' causes are checked below
                assert isinstance(cause, ast.Constant) and isinstance(cause.value, str), \
                    f"{where}: the first argument must be a cause of CATEGORIES, by name"
                assert cause.value in CATEGORIES, f"{where}: {cause.value!r} is not a cause of CATEGORIES"
                calls.append(cause.value)
    assert set(safety._KINDS.values()) <= set(CATEGORIES)
    assert {"emergency stop", "fault", "brakes", "watchdog"} <= set(calls)
