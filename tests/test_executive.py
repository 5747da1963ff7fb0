"""The cyclic executive (runtime/loop/executive.py) with fake components: phase order within
a tick, periods, enabling, the two clocks, deadline-miss policies (on a fake wall clock
whose time the test moves), lateness statistics and the checks on ``add``."""
from __future__ import annotations

import inspect
import random
import time

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from runtime.loop.component import Component
from runtime.loop.executive import PHASES, Executive, MissPolicy, SimClock, TaskStats, WallClock

TICK = 0.001
BIN = 10e-6  # the lateness histogram's bin width


class FakeWallClock(WallClock):
    """A clock that is not simulated (so the executive measures lateness and applies miss
    policies) but whose time only moves when the test (or a fake task) moves it."""

    simulated = False

    def __init__(self):
        super().__init__()
        self.t = 0.0

    def now(self) -> float:
        return self.t

    def wait_until(self, t: float) -> None:
        if self.t < t:
            self.t = t


def late_task(clock: FakeWallClock, late: dict, log: list | None = None):
    """A task that, on tick k, finishes ``late[k]`` seconds after the tick's start."""

    def run(now: float) -> None:
        k = round(now / TICK)
        if log is not None:
            log.append(k)
        if k in late:
            clock.t = max(clock.t, now + late[k])

    return run


# ---- order and periods -------------------------------------------------------------------

def test_tasks_run_in_phase_order_within_a_tick_regardless_of_insertion_order():
    ex = Executive(SimClock(TICK), TICK)
    calls: list[tuple[int, str]] = []
    for phase in ("record", "control", "sense", "act", "plan", "decide"):
        ex.add(phase, lambda now, p=phase: calls.append((round(now / TICK), p)), TICK, phase)
    # two more tasks in one phase: within a phase, insertion order is kept
    ex.add("plan-b", lambda now: calls.append((round(now / TICK), "plan-b")), TICK, "plan")
    ex.add("plan-a", lambda now: calls.append((round(now / TICK), "plan-a")), TICK, "plan")
    ex.run(lambda: False, 3)
    assert ex.ticks == 3
    expected_tick = ["sense", "decide", "plan", "plan-b", "plan-a", "control", "act", "record"]
    for k in range(3):
        assert [name for tick, name in calls if tick == k] == expected_tick
    assert [tick for tick, _ in calls] == sorted(tick for tick, _ in calls)  # tick by tick


def test_phase_order_is_kept_when_tasks_are_added_in_reverse():
    ex = Executive(SimClock(TICK), TICK)
    calls: list[str] = []
    for phase in reversed(PHASES):
        ex.add(phase, lambda now, p=phase: calls.append(p), TICK, phase)
    ex.step()
    assert calls == list(PHASES)


def test_periods_run_on_the_right_ticks():
    ex = Executive(SimClock(TICK), TICK)
    ran: dict[str, list[int]] = {"1ms": [], "5ms": [], "10ms": []}
    times: dict[str, list[float]] = {"1ms": [], "5ms": [], "10ms": []}

    def task(name):
        def run(now):
            ran[name].append(ex.ticks)
            times[name].append(now)
        return run

    ex.add("10ms", task("10ms"), 0.010, "record")
    ex.add("5ms", task("5ms"), 0.005, "plan")
    ex.add("1ms", task("1ms"), 0.001, "control")
    assert ex.run(lambda: False, 31) == 31
    assert ran["1ms"] == list(range(31))
    assert ran["5ms"] == [0, 5, 10, 15, 20, 25, 30]
    assert ran["10ms"] == [0, 10, 20, 30]
    for name, ticks in ran.items():
        assert times[name] == [k * TICK for k in ticks]  # each run gets its tick's start time


def test_periods_on_a_wall_clock_and_the_run_counts():
    clock = FakeWallClock()
    ex = Executive(clock, TICK)
    ran: dict[str, list[int]] = {"1ms": [], "5ms": [], "10ms": []}
    for name, period, phase in (("10ms", 0.010, "sense"), ("1ms", 0.001, "record"), ("5ms", 0.005, "act")):
        ex.add(name, lambda now, n=name: ran[n].append(round(now / TICK)), period, phase)
    ex.run(lambda: False, 31)
    assert ran == {"1ms": list(range(31)), "5ms": list(range(0, 31, 5)), "10ms": [0, 10, 20, 30]}
    stats = ex.statistics()
    assert {name: stats[name]["runs"] for name in ran} == {"1ms": 31, "5ms": 7, "10ms": 4}
    assert all(stats[name]["misses"] == 0 for name in ran)


def test_run_stops_when_until_holds_or_after_max_ticks():
    ex = Executive(SimClock(TICK), TICK)
    count = []
    ex.add("t", lambda now: count.append(now), TICK, "sense")
    assert ex.run(lambda: len(count) >= 7, 100) == 7
    assert ex.ticks == 7
    assert ex.run(lambda: False, 5) == 5
    assert ex.ticks == 12 and len(count) == 12
    assert ex.run(lambda: True, 5) == 0


# ---- enabling ------------------------------------------------------------------------------

def test_disabled_tasks_do_not_run():
    ex = Executive(SimClock(TICK), TICK)
    ran: list[int] = []
    other: list[int] = []
    on = {"value": False}
    ex.add("gated", lambda now: ran.append(ex.ticks), TICK, "control", enabled=lambda: on["value"])
    ex.add("never", lambda now: pytest.fail("a task whose enabled() is False ran"), TICK, "act",
           enabled=lambda: False)
    ex.add("always", lambda now: other.append(ex.ticks), TICK, "record")
    ex.run(lambda: False, 5)
    assert ran == []
    on["value"] = True
    ex.run(lambda: False, 5)
    on["value"] = False
    ex.run(lambda: False, 5)
    assert ran == [5, 6, 7, 8, 9]
    assert other == list(range(15))
    assert ex.statistics()["never"]["runs"] == 0


def test_run_counts_on_the_simulated_clock():
    ex = Executive(SimClock(TICK), TICK)
    ex.add("t", lambda now: None, TICK, "control")
    ex.run(lambda: False, 100)
    assert ex.statistics()["t"]["runs"] == 100


def test_enabled_is_asked_only_on_due_ticks():
    ex = Executive(SimClock(TICK), TICK)
    asked: list[int] = []

    def enabled():
        asked.append(ex.ticks)
        return True

    ex.add("10ms", lambda now: None, 0.010, "plan", enabled=enabled)
    ex.run(lambda: False, 30)
    assert asked == [0, 10, 20]


@pytest.mark.skipif("component" not in inspect.signature(Executive.add).parameters,
                    reason="Executive.add has no component= parameter in this version")
def test_a_task_bound_to_a_component_runs_only_while_it_is_running():
    ex = Executive(SimClock(TICK), TICK)
    comp = Component("fake", TICK)
    ran: list[int] = []
    ex.add("fake", lambda now: ran.append(ex.ticks), TICK, "control", component=comp)
    ex.run(lambda: False, 3)  # unconfigured
    comp.start()
    ex.run(lambda: False, 3)
    comp.stop()
    ex.run(lambda: False, 3)
    comp.start()
    comp.error("broken")  # ERROR: not running
    ex.run(lambda: False, 3)
    assert ran == [3, 4, 5]


# ---- clocks ----------------------------------------------------------------------------------

def test_sim_clock_time_is_exactly_ticks_times_tick_after_a_million_ticks():
    clock = SimClock(TICK)
    ex = Executive(clock, TICK)
    wrong: list[tuple[int, float, float]] = []

    def check(now):
        k = ex.ticks
        fresh = k * 0.001
        if now != fresh or clock.now() != fresh:
            wrong.append((k, now, clock.now()))

    ex.add("check", check, TICK, "sense")
    ex.run(lambda: False, 1_000_001)
    assert wrong == []
    assert ex.ticks == 1_000_001
    assert clock.now() == 1_000_000 * 0.001  # the last tick run was k = 1e6
    # an accumulating clock would have drifted by now:
    acc = 0.0
    for _ in range(1_000_000):
        acc += 0.001
    assert acc != 1_000_000 * 0.001  # (so the comparison above is meaningful)


def test_sim_clock_never_goes_backwards_and_costs_nothing():
    clock = SimClock(TICK)
    t0 = time.perf_counter()
    clock.wait_until(5.0)
    assert time.perf_counter() - t0 < 0.1
    assert clock.now() == 5000 * TICK
    clock.wait_until(1.0)
    assert clock.now() == 5000 * TICK
    clock.wait_until(5.0004)  # rounds to the nearest tick
    assert clock.now() == 5000 * TICK


def test_sim_clock_records_no_lateness_however_long_a_task_takes():
    ex = Executive(SimClock(TICK), TICK)
    ex.add("slow", lambda now: time.sleep(0.003), TICK, "control", policy=MissPolicy("hard"))
    ex.run(lambda: False, 16)
    assert ex.fault is None
    s = ex.tasks[0].stats
    assert s.misses == 0 and s.late_max == 0.0 and sum(s.histogram) == 0
    assert s.exec_max >= 0.003  # execution time is still measured (at least on sampled ticks)


@pytest.mark.parametrize("spin", [0.0008, 0.0])
def test_wall_clock_wait_until_never_returns_before_the_deadline(spin):
    clock = WallClock(spin=spin)
    for d in (-0.001, 0.0, 1e-5, 1e-4, 5e-4, 7.9e-4, 8e-4, 8.1e-4, 1e-3, 2e-3, 5e-3) * 3:
        t = clock.now() + d
        clock.wait_until(t)
        after = clock.now()
        assert after >= t, f"returned {t - after:.2e} s early for a wait of {d} s"
        assert after - t < 0.25  # and does not oversleep wildly


def test_wall_clock_drives_the_executive_at_the_tick_rate():
    clock = WallClock()
    ex = Executive(clock, TICK)
    starts: list[tuple[float, float]] = []
    ex.add("t", lambda now: starts.append((now, clock.now())), TICK, "sense")
    ex.run(lambda: False, 20)
    for scheduled, actual in starts:
        assert actual >= scheduled  # never early
    assert clock.now() >= 19 * TICK


# ---- miss policies (fake wall clock) ---------------------------------------------------------

def test_on_time_tasks_do_not_miss():
    clock = FakeWallClock()
    ex = Executive(clock, TICK)
    ex.add("ok", late_task(clock, {k: 0.0004 for k in range(50)}), TICK, "control", policy=MissPolicy("hard"))
    ex.run(lambda: False, 50)
    assert ex.fault is None
    assert ex.tasks[0].stats.misses == 0
    assert ex.tasks[0].stats.late_max == pytest.approx(0.0004)


def test_hard_policy_faults_at_the_first_miss():
    clock = FakeWallClock()
    ex = Executive(clock, TICK)
    ticks_run: list[int] = []
    ex.add("servo", late_task(clock, {5: 0.0015}, ticks_run), TICK, "control", policy=MissPolicy("hard"))
    ex.run(lambda: False, 5)
    assert ex.fault is None
    ex.step()  # tick 5 finishes 1.5 ms after its start: a miss of a 1 ms deadline
    assert ex.fault is not None
    assert "servo" in ex.fault and "hard" in ex.fault
    assert ex.tasks[0].stats.misses == 1


def test_hard_policy_fault_names_the_first_missing_task():
    clock = FakeWallClock()
    ex = Executive(clock, TICK)
    ex.add("first", late_task(clock, {3: 0.0015}), TICK, "plan", policy=MissPolicy("hard"))
    ex.add("second", late_task(clock, {3: 0.0015, 8: 0.0015}), TICK, "act", policy=MissPolicy("hard"))
    ex.run(lambda: False, 10)
    assert "first" in ex.fault and "second" not in ex.fault


def test_lateness_is_compared_with_the_tasks_own_period():
    clock = FakeWallClock()
    ex = Executive(clock, TICK)
    # 3 ms late: a miss for a 1 ms task, within the deadline of a 5 ms task
    ex.add("slow5", late_task(clock, {0: 0.003, 5: 0.0045}), 0.005, "plan", policy=MissPolicy("hard"))
    ex.run(lambda: False, 10)
    assert ex.fault is None
    assert ex.tasks[0].stats.misses == 0
    ex.add("fast1", late_task(clock, {12: 0.003}), TICK, "control", policy=MissPolicy("hard"))
    ex.run(lambda: False, 5)
    assert ex.fault is not None and "fast1" in ex.fault


def test_firm_policy_faults_only_after_more_than_limit_misses_within_the_window():
    clock = FakeWallClock()
    ex = Executive(clock, TICK)
    misses = {10: 0.0015, 20: 0.0015, 30: 0.0015, 40: 0.0015}
    ex.add("servo", late_task(clock, misses), TICK, "control", policy=MissPolicy("firm", limit=3, window=100))
    ex.run(lambda: False, 40)  # ticks 0..39: three misses (10, 20, 30) = limit: no fault
    assert ex.tasks[0].stats.misses == 3
    assert ex.fault is None
    ex.step()  # tick 40: the fourth within 100 ticks
    assert ex.tasks[0].stats.misses == 4
    assert ex.fault is not None and "servo" in ex.fault and "firm" in ex.fault


def test_firm_policy_forgets_misses_older_than_the_window():
    clock = FakeWallClock()
    ex = Executive(clock, TICK)
    misses = {k: 0.0015 for k in range(0, 2000, 100)}  # twenty misses, one per window
    ex.add("servo", late_task(clock, misses), TICK, "control", policy=MissPolicy("firm", limit=1, window=100))
    ex.run(lambda: False, 2000)
    assert ex.tasks[0].stats.misses == 20
    assert ex.fault is None


@pytest.mark.parametrize("second, faults", [(110, False), (109, True)])
def test_firm_policy_window_boundary(second, faults):
    """limit=1, window=10: misses at ticks 100 and 110 are not 'within 10 ticks' (the
    older one has left the window), at 100 and 109 they are."""
    clock = FakeWallClock()
    ex = Executive(clock, TICK)
    ex.add("t", late_task(clock, {100: 0.0015, second: 0.0015}), TICK, "control",
           policy=MissPolicy("firm", limit=1, window=10))
    ex.run(lambda: False, 150)
    assert ex.tasks[0].stats.misses == 2
    assert (ex.fault is not None) is faults


def test_soft_policy_only_counts():
    clock = FakeWallClock()
    ex = Executive(clock, TICK)
    ex.add("report", late_task(clock, {k: 0.0015 for k in range(0, 100, 2)}), TICK, "record",
           policy=MissPolicy("soft"))
    ex.add("default", late_task(clock, {}), TICK, "record")  # the default policy is soft too
    ex.run(lambda: False, 100)
    assert ex.fault is None
    assert ex.tasks[0].stats.misses == 50
    assert ex.statistics()["report"]["misses"] == 50


def test_lateness_statistics_on_a_fake_wall_clock():
    clock = FakeWallClock()
    ex = Executive(clock, TICK)
    late = {k: 0.000255 for k in range(100)}  # bin 25 (250..260 us)
    late[50] = 0.000755  # bin 75
    ex.add("t", late_task(clock, late), TICK, "control")
    ex.run(lambda: False, 100)
    s = ex.tasks[0].stats
    assert s.runs == 100
    assert s.late_max == pytest.approx(0.000755)
    assert sum(s.histogram) == 100
    assert s.histogram[25] == 99 and s.histogram[75] == 1
    assert s.percentile(0.5) == pytest.approx(26 * BIN)
    assert s.percentile(0.99) == pytest.approx(26 * BIN)
    assert s.percentile(1.0) == pytest.approx(76 * BIN)
    summary = ex.statistics()["t"]
    assert set(summary) >= {"runs", "misses", "exec_mean_us", "exec_max_us", "late_max_us", "late_p99_us"}
    assert summary["late_max_us"] == pytest.approx(755.0)
    assert summary["late_p99_us"] == pytest.approx(260.0)


# ---- TaskStats.percentile ----------------------------------------------------------------------

def test_percentile_of_no_samples_is_zero():
    assert TaskStats().percentile(0.99) == 0.0


def test_percentile_is_the_upper_edge_of_the_bin_holding_the_quantile():
    s = TaskStats()
    s.histogram[0] = 99
    s.histogram[100] = 1
    assert s.percentile(0.5) == pytest.approx(1 * BIN)
    assert s.percentile(0.99) == pytest.approx(1 * BIN)
    assert s.percentile(0.995) == pytest.approx(101 * BIN)
    assert s.percentile(1.0) == pytest.approx(101 * BIN)


def test_percentile_is_monotonic_in_q():
    s = TaskStats()
    rng = random.Random(3)
    for _ in range(1000):
        s.histogram[rng.randrange(0, 300)] += 1
    qs = [i / 100 for i in range(1, 101)]
    values = [s.percentile(q) for q in qs]
    assert values == sorted(values)
    assert values[-1] <= 300 * BIN


def test_percentile_of_the_overflow_bin():
    s = TaskStats()
    s.histogram[len(s.histogram) - 1] = 4  # everything 20 ms or later
    assert s.percentile(0.5) == pytest.approx(len(s.histogram) * BIN)


def test_percentile_zero_is_the_lowest_occupied_bin():
    s = TaskStats()
    s.histogram[100] = 5  # every sample ~1 ms late
    assert s.percentile(0.0) == pytest.approx(101 * BIN)


# ---- add() checks --------------------------------------------------------------------------------

@pytest.mark.parametrize("period", [0.0015, 0.0005, 0.0, -0.001, 0.0025, 0.0101, 1e-6])
def test_a_period_that_is_not_a_multiple_of_the_tick_is_refused(period):
    ex = Executive(SimClock(TICK), TICK)
    with pytest.raises(ValueError):
        ex.add("bad", lambda now: None, period, "plan")
    assert ex.tasks == []


@pytest.mark.parametrize("period, ticks", [(0.001, 1), (0.005, 5), (0.01, 10), (0.1, 100), (0.003, 3)])
def test_periods_that_are_multiples_of_the_tick_are_accepted(period, ticks):
    ex = Executive(SimClock(TICK), TICK)
    assert ex.add("ok", lambda now: None, period, "plan").period == ticks


def test_an_unknown_phase_is_refused():
    ex = Executive(SimClock(TICK), TICK)
    with pytest.raises(ValueError):
        ex.add("bad", lambda now: None, TICK, "think")


def test_periods_with_another_tick():
    ex = Executive(SimClock(0.002), 0.002)
    with pytest.raises(ValueError):
        ex.add("bad", lambda now: None, 0.001, "plan")
    ex.add("ok", lambda now: None, 0.01, "plan")
    assert ex.tasks[0].period == 5


def test_hard_fault_message_gives_the_deadline_in_ms_for_any_tick():
    tick = 0.002
    clock = FakeWallClock()
    ex = Executive(clock, tick)

    def run(now):
        clock.t = now + 0.015  # 15 ms late for a 10 ms deadline

    ex.add("slow", run, 0.010, "plan", policy=MissPolicy("hard"))
    ex.step()
    assert ex.fault is not None
    assert "10 ms" in ex.fault, ex.fault


# ---- the simulated clock's short path -------------------------------------------------------

_ACTIONS = ("start", "stop", "error", "recover")


def _scheduled_system(seed_tasks, actions, short: bool):
    """An executive with components, tasks bound to them (or to none) and, inside the tasks'
    runs, lifecycle changes at given (tick, task) points; returns it and the run log."""
    ex = Executive(SimClock(TICK), TICK)
    ex._short = short  # white box: the reference takes the full per-task path on every tick
    comps = [Component(f"c{i}", TICK) for i in range(3)]
    log: list[tuple[int, str]] = []

    def make(name: str):
        def run(now: float) -> None:
            k = round(now / TICK)
            log.append((k, name))
            for action, c in actions.get((k, name), ()):
                comp = comps[c]
                {"start": comp.start, "stop": comp.stop, "error": lambda: comp.error("x"),
                 "recover": comp.recover}[action]()
        return run

    for i, (period, phase, c) in enumerate(seed_tasks):
        ex.add(f"t{i}", make(f"t{i}"), period * TICK, PHASES[phase],
               component=None if c is None else comps[c])
    return ex, log


@settings(max_examples=60, deadline=None)
@given(st.lists(st.tuples(st.sampled_from([1, 2, 5, 10]), st.integers(0, len(PHASES) - 1),
                          st.one_of(st.none(), st.integers(0, 2))), min_size=1, max_size=6),
       st.lists(st.tuples(st.integers(0, 59), st.integers(0, 5), st.sampled_from(_ACTIONS), st.integers(0, 2)),
                max_size=25))
def test_property_the_short_path_runs_the_same_tasks_on_the_same_ticks(seed_tasks, raw_actions):
    """On the simulated clock most ticks skip the per-task checks; lifecycle changes (also
    in the middle of a tick, by an earlier task) must give exactly the runs and run counts
    of the full path."""
    actions: dict = {}
    for k, t, action, c in raw_actions:
        actions.setdefault((k, f"t{t % len(seed_tasks)}"), []).append((action, c))
    fast, fast_log = _scheduled_system(seed_tasks, actions, short=True)
    slow, slow_log = _scheduled_system(seed_tasks, actions, short=False)
    fast.run(lambda: False, 60)
    slow.run(lambda: False, 60)
    assert fast_log == slow_log
    assert ({n: s["runs"] for n, s in fast.statistics().items()}
            == {n: s["runs"] for n, s in slow.statistics().items()})


def test_a_component_started_by_an_earlier_task_runs_in_the_same_tick_on_the_short_path():
    ex = Executive(SimClock(TICK), TICK)
    comp = Component("servo", TICK)
    ran: list[int] = []
    ex.add("supervisor", lambda now: comp.start() if round(now / TICK) == 3 else None, TICK, "decide")
    ex.add("servo", lambda now: ran.append(round(now / TICK)), TICK, "control", component=comp)
    ex.run(lambda: False, 6)
    assert ran == [3, 4, 5]  # tick 3 is not a sampled tick: the short path found the change
    assert ex.statistics()["servo"]["runs"] == 3


def test_run_counts_survive_a_period_change_and_a_statistics_reset():
    ex = Executive(SimClock(TICK), TICK)
    ex.add("t", lambda now: None, TICK, "control")
    ex.run(lambda: False, 20)
    ex.set_period("t", 0.002)
    ex.run(lambda: False, 20)  # ticks 20..39, every second one
    assert ex.statistics()["t"]["runs"] == 30
    ex.reset_statistics()
    ex.run(lambda: False, 10)
    assert ex.statistics()["t"]["runs"] == 5


def test_the_wall_clock_spins_briefly_only_where_its_thread_runs_real_time():
    """A SCHED_FIFO loop wakes on time without a long spin; a long one would take most of a
    core from the host. At normal scheduling the spin stays long (late wake-ups)."""
    import os
    import threading

    from runtime.loop.executive import SPIN_NORMAL, SPIN_REALTIME

    clock = WallClock()
    clock.wait_until(clock.now())
    assert clock.spin == (SPIN_NORMAL if os.sched_getscheduler(0) == os.SCHED_OTHER else SPIN_REALTIME)
    got: list[float] = []

    def loop() -> None:
        try:
            os.sched_setscheduler(0, os.SCHED_FIFO, os.sched_param(1))
        except (PermissionError, OSError):
            got.append(-1.0)
            return
        c = WallClock()
        c.wait_until(c.now() + 0.002)
        got.append(c.spin)

    t = threading.Thread(target=loop)
    t.start()
    t.join()
    if got == [-1.0]:
        pytest.skip("this host refuses SCHED_FIFO")
    assert got == [SPIN_REALTIME]
    assert WallClock(spin=0.0005).spin == 0.0005
