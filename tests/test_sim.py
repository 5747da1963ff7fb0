"""The simulated robot (runtime/hardware/sim/robot.py) and the alpha-beta estimator
(runtime/hardware/sim/estimator.py): drive lag and offset, brakes, hard stops, encoder, index
pulses, homing sensors, faults, digital I/O, determinism; estimator tracking."""
from __future__ import annotations

import math
import random
import statistics

import pytest

from compiler.spec import parse_spec
from runtime.hardware.sim import FAULTS, AlphaBeta, SimRobot, critically_damped_gains

from conftest import SPEC
DT = 0.001
N = len(SPEC.axes)
ZERO = (0.0,) * N


def one_axis_spec(simulation: str = "", **axis) -> object:
    """A one-axis robot; keyword arguments override the axis' keys. (Its in_position_timeout
    is long: a long axis with a fine encoder, whose servo's integral may take seconds to
    settle it; these tests do not run the servo.)"""
    keys = {"min": -100.0, "max": 100.0, "max_velocity": 200.0, "max_acceleration": 1000.0,
            "max_jerk": 10000.0, "gear_ratio": 100.0, "encoder_counts": 4096}
    keys.update(axis)
    lines = "\n".join(f"{k} = {v!r}" for k, v in keys.items())
    text = f'[robot]\nname = "test_arm"\n\n[[axis]]\nname = "J1"\nkind = "revolute"\n{lines}\n'
    if simulation:
        text += f"\n[simulation]\n{simulation}\n"
    text += "\n[safety]\nin_position_timeout = 60.0\n"
    return parse_spec(text, "test.spc")


def run(robot: SimRobot, commands, ticks: int, check=None) -> None:
    for _ in range(ticks):
        robot.step(DT, commands)
        if check is not None:
            check(robot)


def released(spec=SPEC, seed: int = 0) -> SimRobot:
    robot = SimRobot(spec, seed)
    robot.release_brakes()
    run(robot, (0.0,) * len(spec.axes), 60)
    assert robot.brakes_released()
    return robot


# ---- power-up ---------------------------------------------------------------------------

def test_power_up_parks_near_home_with_encoders_at_zero_and_brakes_on():
    for seed in range(20):
        robot = SimRobot(SPEC, seed)
        for axis, x in zip(SPEC.axes, robot.true_positions):
            assert abs(x - axis.home) <= 3.0
            assert axis.min <= x <= axis.max
        counts, events, latched, _ = robot.read()
        assert counts == (0,) * N and events == (0,) * N and latched == (0,) * N
        assert robot.power_up_positions == robot.true_positions
        assert robot.brakes_applied() and not robot.brakes_released()
    assert len({SimRobot(SPEC, s).true_positions for s in range(20)}) == 20


def test_power_up_position_is_clipped_into_the_limits():
    # (the sensor 15 deg above min: room for homing's index search, compiler.params.least_gear_ratio)
    spec = one_axis_spec("park_spread = 3.0", min=-10.0, max=10.0, home=9.0, sensor_position=5.0)
    parks = [SimRobot(spec, seed).true_positions[0] for seed in range(200)]
    assert all(6.0 <= x <= 10.0 for x in parks)
    assert parks.count(10.0) > 0  # some drew beyond the limit and were clipped onto it


# ---- drive ------------------------------------------------------------------------------

def test_lag_response_reaches_63_percent_after_one_time_constant():
    robot = released()
    tau = SPEC.simulation.drive_time_constant
    ticks = round(tau / DT)
    v0 = robot.true_velocities
    command = (50.0,) * N
    run(robot, command, ticks)
    for i in range(N):
        target = 50.0 + robot.drive_offsets[i]
        fraction = (robot.true_velocities[i] - v0[i]) / (target - v0[i])
        assert fraction == pytest.approx(1.0 - math.exp(-1.0), abs=1e-9)
    run(robot, command, 5 * ticks)  # 6 tau in all
    for i in range(N):
        assert robot.true_velocities[i] == pytest.approx(50.0 + robot.drive_offsets[i], rel=0.003)


def test_exact_discretisation_is_independent_of_the_step_size():
    fine, coarse = released(), released()
    command = (30.0,) * N
    for _ in range(100):
        fine.step(DT / 10, command)
    coarse.step(DT * 10, command)
    assert fine.true_positions == pytest.approx(coarse.true_positions, abs=1e-9)
    assert fine.true_velocities == pytest.approx(coarse.true_velocities, abs=1e-9)


def test_drive_has_a_constant_unknown_velocity_offset():
    robot = released()
    offsets = robot.drive_offsets
    assert all(0.0 < abs(b) <= 0.5 for b in offsets)
    assert len(set(offsets)) == N
    start = robot.true_positions
    run(robot, ZERO, 1000)  # commanded to stand still for 1 s, it drifts
    for i in range(N):
        assert robot.true_velocities[i] == pytest.approx(offsets[i], rel=1e-6)
        assert robot.true_positions[i] - start[i] == pytest.approx(offsets[i] * 1.0, rel=1e-3)
    assert SimRobot(SPEC, 1).drive_offsets != offsets
    still = released(one_axis_spec("max_drive_offset = 0.0"))
    before = still.true_positions
    run(still, (0.0,), 1000)
    assert still.true_positions == before


def test_command_saturates_and_nan_counts_as_zero():
    spec = one_axis_spec("max_drive_offset = 0.0")
    robot = released(spec)
    run(robot, (1e9,), 100)
    assert robot.true_velocities[0] == pytest.approx(1.5 * 200.0)
    run(robot, (float("nan"),), 100)
    assert abs(robot.true_velocities[0]) < 1e-6
    assert all(math.isfinite(x) for x in robot.true_positions)


def test_commands_may_be_any_sequence_of_numbers_but_one_per_axis():
    as_tuple, as_list = released(SPEC), released(SPEC)
    n = len(SPEC.axes)
    run(as_tuple, tuple(float(i) for i in range(n)), 20)
    run(as_list, list(range(n)), 20)  # a list of integers: the same commands
    assert as_list.true_positions == as_tuple.true_positions
    with pytest.raises(ValueError, match=f"{n - 1} velocity commands for {n} axes"):
        as_tuple.step(DT, (0.0,) * (n - 1))


# ---- brakes -------------------------------------------------------------------------------

def test_brakes_hold_at_power_up_and_take_time_to_release_and_apply():
    robot = SimRobot(SPEC, 3)
    start = robot.true_positions
    run(robot, (100.0,) * N, 200)
    assert robot.true_positions == start and robot.true_velocities == ZERO
    assert robot.read()[0] == (0,) * N

    robot.release_brakes()
    run(robot, (100.0,) * N, 49)
    assert not robot.brakes_released() and not robot.brakes_applied()
    assert robot.true_positions == start
    run(robot, (100.0,) * N, 1)  # 50 ms: effective
    assert robot.brakes_released() and robot.true_positions == start
    run(robot, (100.0,) * N, 1)
    assert all(x > s for x, s in zip(robot.true_positions, start))

    run(robot, (50.0,) * N, 100)
    robot.apply_brakes()
    before = robot.true_positions
    run(robot, (50.0,) * N, 49)
    assert robot.brakes_released() and not robot.brakes_applied()
    assert all(x > b for x, b in zip(robot.true_positions, before))  # still moving
    run(robot, (50.0,) * N, 1)
    assert robot.brakes_applied() and not robot.brakes_released()
    assert robot.true_velocities == ZERO
    held, counts = robot.true_positions, robot.read()[0]
    run(robot, (50.0,) * N, 100)
    assert robot.true_positions == held and robot.read()[0] == counts


def test_brake_commands_cancel_each_other():
    robot = SimRobot(SPEC)
    robot.release_brakes()
    run(robot, ZERO, 30)
    robot.apply_brakes()  # changes its mind: the brakes stay on
    assert robot.brakes_applied()
    run(robot, ZERO, 100)
    assert robot.brakes_applied()
    robot.release_brakes()
    run(robot, ZERO, 30)
    robot.release_brakes()  # asking again does not restart the time
    run(robot, ZERO, 20)
    assert robot.brakes_released()


# ---- hard stops ---------------------------------------------------------------------------

def test_hard_stops_beyond_the_software_limits():
    robot = released()
    margin = SPEC.simulation.end_stop_margin
    hi = tuple(a.max + margin for a in SPEC.axes)
    lo = tuple(a.min - margin for a in SPEC.axes)
    assert robot.end_stops == tuple(zip(lo, hi))

    def within(r):
        assert all(l <= x <= h for l, x, h in zip(lo, r.true_positions, hi))

    run(robot, tuple(a.max_velocity for a in SPEC.axes), 3000, within)
    assert robot.true_positions == hi
    assert all(v <= 0.0 for v in robot.true_velocities)
    run(robot, tuple(-a.max_velocity for a in SPEC.axes), 3000, within)
    assert robot.true_positions == lo
    assert all(v >= 0.0 for v in robot.true_velocities)
    run(robot, tuple(a.max_velocity for a in SPEC.axes), 10)  # and it leaves them again
    assert all(x > l for x, l in zip(robot.true_positions, lo))


# ---- encoder ------------------------------------------------------------------------------

def test_encoder_counts_from_zero_at_power_up_quantised_by_floor():
    robot = released()
    p0 = robot.power_up_positions
    cpu = [a.counts_per_unit for a in SPEC.axes]
    seen = [set() for _ in range(N)]

    def quantised(r):
        counts = r.read()[0]
        for i, x in enumerate(r.true_positions):
            assert counts[i] <= (x - p0[i]) * cpu[i] < counts[i] + 1
            seen[i].add(counts[i])

    # slow (0.3 deg/s, offset compensated, < 1 count per tick): every count passes by
    run(robot, tuple(-0.3 - b for b in robot.drive_offsets), 300, quantised)
    run(robot, tuple(0.3 - b for b in robot.drive_offsets), 600, quantised)
    for i in range(N):
        values = sorted(seen[i])
        assert len(values) > 1 and values == list(range(values[0], values[-1] + 1))


# ---- index pulses -------------------------------------------------------------------------

def check_index(robot: SimRobot, command, ticks: int) -> int:
    """Step, checking every pulse's latched count; returns the number of pulses."""
    p0 = robot.power_up_positions
    pulses = 0
    for _ in range(ticks):
        before = robot.true_positions
        _, events_before, _, _ = robot.read()
        robot.step(DT, command)
        _, events, latched, _ = robot.read()
        for i, axis in enumerate(robot.spec.axes):
            spacing, cpu = axis.index_spacing, axis.counts_per_unit
            crossed = abs(math.floor(robot.true_positions[i] / spacing) - math.floor(before[i] / spacing))
            assert events[i] - events_before[i] == crossed
            assert robot.index_active[i] == (crossed > 0)
            if crossed:
                pulses += crossed
                z = p0[i] + latched[i] / cpu  # where the latch says the pulse was
                k = round(z / spacing)
                assert abs(z - k * spacing) <= 1.0 / cpu
                low, high = sorted((before[i], robot.true_positions[i]))
                assert low - 1.0 / cpu <= k * spacing <= high + 1.0 / cpu
    return pulses


def test_index_pulses_at_multiples_of_the_index_spacing():
    robot = released()
    start = robot.true_positions
    pulses = check_index(robot, (100.0,) * N, 200)
    pulses += check_index(robot, (-100.0,) * N, 400)
    assert pulses > 6 * 10
    fine = released(one_axis_spec(gear_ratio=1000.0, max_velocity=1000.0, min=-1000.0, max=1000.0))  # 0.36 deg apart
    assert check_index(fine, (800.0,), 100) > 150  # two or three pulses in one tick
    assert SPEC.axes[0].index_spacing == pytest.approx(360.0 / 160.0)
    end = robot.true_positions
    for i, axis in enumerate(SPEC.axes):  # the counters only grow, whatever the direction
        up = math.floor(max(robot.true_positions[i], start[i]) / axis.index_spacing)
        assert robot.read()[1][i] > abs(up - math.floor(end[i] / axis.index_spacing))


def test_index_pulses_are_never_missed_by_a_5ms_reader_at_high_speed():
    spec = one_axis_spec(gear_ratio=1000.0, min=-1000.0, max=1000.0)  # 0.36 deg between pulses
    robot = released(spec)
    spacing, cpu = spec.axes[0].index_spacing, spec.axes[0].counts_per_unit
    start = robot.true_positions[0]
    last_events = robot.read()[1][0]
    seen = flagged = 0
    for tick in range(1, 1001):
        robot.step(DT, (200.0,))
        if tick % 5 == 0:  # the reader
            flagged += robot.index_active[0]
            _, events, latched, _ = robot.read()
            new = events[0] - last_events
            last_events = events[0]
            seen += new
            if new:  # the latch holds the last pulse before the read
                last_z = math.floor(robot.true_positions[0] / spacing) * spacing
                assert robot.power_up_positions[0] + latched[0] / cpu == pytest.approx(last_z, abs=1.0 / cpu)
    crossed = math.floor(robot.true_positions[0] / spacing) - math.floor(start / spacing)
    assert crossed > 500 and seen == crossed
    assert flagged < crossed / 2  # about 3 pulses per read: a reader of the flag alone loses most


# ---- homing sensor ------------------------------------------------------------------------

def test_homing_sensor_window():
    robot = released()
    at = [a.sensor_position for a in SPEC.axes]
    window = [a.sensor_window for a in SPEC.axes]
    entered = [None] * N

    def sensor(r):
        active = r.read()[3]
        for i, x in enumerate(r.true_positions):
            assert active[i] == (abs(x - at[i]) <= window[i])
            if active[i] and entered[i] is None:
                entered[i] = x

    run(robot, tuple(-a.search_velocity for a in SPEC.axes), 2000, sensor)
    for i in range(N):
        assert entered[i] is not None
        assert at[i] + window[i] - 0.01 <= entered[i] <= at[i] + window[i]


# ---- faults -------------------------------------------------------------------------------

def test_fault_sensor_dead():
    robot = released()
    robot.inject("sensor_dead", 0)
    assert robot.faults() == (("sensor_dead", 0),)
    hits = [0] * N

    def count(r):
        for i, active in enumerate(r.read()[3]):
            hits[i] += active

    run(robot, tuple(-a.search_velocity for a in SPEC.axes), 2000, count)
    assert hits[0] == 0 and all(h > 0 for h in hits[1:])
    robot.clear_faults()
    hits = [0] * N
    run(robot, tuple(a.search_velocity for a in SPEC.axes), 2000, count)
    assert hits[0] > 0


def test_fault_encoder_frozen():
    robot = released()
    cpu = SPEC.axes[0].counts_per_unit
    robot.inject("encoder_frozen", 0)
    counts, events, _, _ = robot.read()
    run(robot, (50.0,) * N, 200)
    counts2, events2, _, _ = robot.read()
    assert counts2[0] == counts[0] and events2[0] == events[0]
    assert all(c2 != c for c2, c in zip(counts2[1:], counts[1:]))
    assert all(e2 > e for e2, e in zip(events2[1:], events[1:]))
    robot.clear_faults()
    x = robot.true_positions[0]
    run(robot, (50.0,) * N, 100)
    counts3 = robot.read()[0]
    # it counts on from where it froze: the counts it missed stay missed
    assert counts3[0] - counts2[0] == pytest.approx((robot.true_positions[0] - x) * cpu, abs=1.0)


def test_fault_drive_dead():
    robot = released()
    run(robot, (50.0,) * N, 50)
    robot.inject("drive_dead", 0)
    run(robot, (50.0,) * N, 50)  # 10 time constants
    assert abs(robot.true_velocities[0]) < 50.0 * math.exp(-9.0)
    assert robot.true_velocities[1] == pytest.approx(50.0 + robot.drive_offsets[1], rel=1e-3)
    stopped = robot.true_positions[0]
    run(robot, (50.0,) * N, 100)
    assert robot.true_positions[0] == pytest.approx(stopped, abs=1e-4)
    robot.clear_faults()
    assert robot.faults() == ()
    run(robot, (50.0,) * N, 50)
    assert robot.true_velocities[0] == pytest.approx(50.0 + robot.drive_offsets[0], rel=1e-3)


def test_inject_refuses_unknown_faults_and_axes():
    robot = SimRobot(SPEC)
    with pytest.raises(ValueError, match="encoder_frozen"):
        robot.inject("encoder_dead", 0)
    with pytest.raises(IndexError, match="axes 0..5"):
        robot.inject("drive_dead", 6)
    assert set(FAULTS) == {"sensor_dead", "encoder_frozen", "drive_dead"}


# ---- digital I/O --------------------------------------------------------------------------

def test_digital_io_numbered_from_one():
    robot = SimRobot(SPEC)
    assert robot.inputs == (False,) * SPEC.inputs and robot.outputs == (False,) * SPEC.outputs
    robot.set_input(1, True)
    robot.set_output(16, True)
    assert robot.input(1) and robot.inputs[0] and not robot.input(2)
    assert robot.output(16) and robot.outputs[15]
    with pytest.raises(IndexError, match="inputs 1..16"):
        robot.set_input(0, True)
    with pytest.raises(IndexError, match="outputs 1..16"):
        robot.set_output(17, True)


# ---- determinism --------------------------------------------------------------------------

def scenario(seed: int):
    robot = SimRobot(SPEC, seed)
    commands = random.Random(123)
    trace = []
    for tick in range(3000):
        if tick == 10:
            robot.release_brakes()
        elif tick == 1000:
            robot.inject("drive_dead", 2)
            robot.inject("encoder_frozen", 4)
        elif tick == 1500:
            robot.clear_faults()
        elif tick == 2500:
            robot.apply_brakes()
        robot.step(DT, tuple(commands.uniform(-80.0, 80.0) for _ in range(N)))
        trace.append((robot.read(), robot.true_positions, robot.true_velocities))
    return trace


def test_deterministic_for_the_same_seed():
    first, second = scenario(5), scenario(5)
    assert first == second  # bit-identical floats
    assert scenario(6) != first


# ---- estimator ----------------------------------------------------------------------------

def quantised(x: float, cpu: float) -> float:
    return math.floor(x * cpu) / cpu


def test_estimator_converges_on_a_ramp_and_is_unbiased():
    cpu = SPEC.axes[0].counts_per_unit
    q = 1.0 / cpu
    speed = 100.0
    f = AlphaBeta(1, DT)
    f.reset([quantised(0.1234, cpu)])  # starts believing the axis stands still
    velocity_errors, position_errors = [], []
    for k in range(1, 2001):
        x = 0.1234 + speed * k * DT
        positions, velocities = f.update([quantised(x, cpu)])
        if k == 50:
            assert abs(velocities[0] - speed) < 0.005 * speed
        if k > 100:
            velocity_errors.append(velocities[0] - speed)
            position_errors.append(positions[0] - x)
    assert abs(statistics.mean(velocity_errors)) < 1e-3
    assert statistics.pstdev(velocity_errors) < 0.05  # a raw 1 ms difference: q / dt = 0.55
    # no bias beyond the encoder's own (floor: q / 2 low on average)
    assert statistics.mean(position_errors) == pytest.approx(-q / 2, abs=0.1 * q)


def test_estimator_on_the_simulated_robot():
    robot = released()
    cpu = [a.counts_per_unit for a in SPEC.axes]
    f = AlphaBeta(N, DT)
    f.reset((0.0,) * N)
    f.reset([c / k for c, k in zip(robot.read()[0], cpu)], robot.true_velocities)
    command = (60.0,) * N
    for _ in range(50):
        robot.step(DT, command)
        positions, velocities = f.update([c / k for c, k in zip(robot.read()[0], cpu)])
    for i in range(N):
        assert abs(velocities[i] - robot.true_velocities[i]) < 0.5
        true = robot.true_positions[i] - robot.power_up_positions[i]
        assert abs(positions[i] - true) < 0.05


def test_estimator_gains():
    alpha, beta = critically_damped_gains(DT)
    f = AlphaBeta(2, DT)
    assert (f.alpha, f.beta) == (alpha, beta)
    theta = math.exp(-DT / 0.006)
    assert alpha == pytest.approx(1 - theta**2) and beta == pytest.approx((1 - theta) ** 2)
    # both poles of the error dynamics at theta: s^2 - (2 - a - b) s + (1 - a) = (s - theta)^2
    assert 2 - alpha - beta == pytest.approx(2 * theta) and 1 - alpha == pytest.approx(theta**2)
    with pytest.raises(ValueError, match="unstable"):
        AlphaBeta(1, DT, alpha=0.5, beta=3.5)
    first = AlphaBeta(2, DT).update([1.0, 2.0])  # without reset: starts at the measurement
    assert first == ((1.0, 2.0), (0.0, 0.0))
