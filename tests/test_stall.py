"""A stall of the host (the loop preempted for up to 0.7 s) under the soft deadline
policy never faults a healthy arm, in any phase (issue 26, fault 5).

The stall is injected deterministically by :class:`StallClock`: a clock that is not
simulated (the executive measures lateness and applies the deadline policy, the
wall-clock paths are taken) but whose time only moves as the
ticks ask, except once, at a chosen tick of a chosen phase, where it jumps ahead by the
stall's length; the ticks then catch up one after another, late, as a real loop does
after a preemption. Every component must count in the ticks' time (``clock.tick_time``)
and never in the clock's ``now()``, which lies ahead of the ticks until they have caught
up: a move whose timeline started at ``now()`` made the servo's reference jump by where
the move was 0.7 s later, and the safety supervisor stopped the arm.
"""
from __future__ import annotations


import pytest
from hypothesis import HealthCheck, example, given, settings
from hypothesis import strategies as st

from compiler.driver import compile_source
from runtime.loop.system import RobotSystem, RunOptions
from runtime.timing import TICK

from conftest import ROOT, SPEC, examples
#: Two moves (one blended into a lin) after homing: Move Robot lasts about 1.9 s.
SOURCE = """program stall;
system_specification "lola15.spc";
seq
  move ptp joint(mainjoint(30, -20, 20, 10, 0, 0)) speed_ptp := 0.5 acc_ptp := 0.5;
  move ptp joint(mainjoint(-10, 0, 10, 0, 20, 0)) speed_ptp := 0.8;
endseq
endprogram;
"""
PROGRAM = compile_source(SOURCE, str(ROOT / "programs" / "stall.irl")).program

#: The phases a stall is put in: a state of the supervisor, or a step of the homing
#: sequence ("sensor", "index", "start position"), and how many ticks into it the stall
#: may come at the latest (each phase lasts longer than that with this program).
PHASES = {"Start Robot": 45, "Calibrate Offsets": 250, "sensor": 400, "index": 300, "start position": 400,
          "Move Robot": 1200, "Stop Robot": 40}


class InlinePlanner:
    """The planning worker's interface, planning at once: as a worker that is done within
    the tick (deterministic; on a real worker the move would start a few ticks later)."""

    def submit(self, job):
        job.run()
        return job


class StallClock:
    """Not simulated, deterministic: ``now()`` is the last tick's time, except that at
    the first tick where ``when()`` holds it jumps ``stall`` seconds ahead; the ticks
    after it find themselves late until the schedule has caught up."""

    simulated = False

    def __init__(self, when, stall: float):
        self.when, self.stall = when, stall
        self.t = 0.0
        self.tick_time = 0.0
        self.stalled_at: float | None = None

    def now(self) -> float:
        return self.t

    def wait_until(self, t: float) -> None:
        self.tick_time = t
        if self.stalled_at is None and self.when():
            self.stalled_at = t
            self.t = max(self.t, t) + self.stall  # preempted: the tick starts this late
        self.t = max(self.t, t)


def phase_of(system) -> str | None:
    state = system.supervisor.fsm.state
    if state == "Initialization Sequence":
        step = system.init.step_name
        return next((name for name in ("sensor", "index", "start position") if step.startswith(name)), None)
    return state


def run_with_stall(phase: str, ticks_in: int, stall: float) -> None:
    """Run SOURCE from power-up with a stall of ``stall`` s ``ticks_in`` ticks into
    ``phase``; assert that the stall happened, nothing faulted, and the servo's 1 ms
    reference never moved faster than the axes' velocity limits allow."""
    box: dict = {}
    seen = {"phase": None, "ticks": 0}

    def when() -> bool:
        current = phase_of(box["system"])
        if current != seen["phase"]:
            seen["phase"], seen["ticks"] = current, 0
        seen["ticks"] += 1
        return current == phase and seen["ticks"] > ticks_in

    clock = StallClock(when, stall)
    system = RobotSystem(SPEC, RunOptions(deadline_policy="soft", max_time=60.0), clock=clock)
    box["system"] = system
    system.trajectory.motion.worker = InlinePlanner()
    shifts = [0.0] * len(SPEC.axes)  # homing's encoder resets move the coordinates, not the reference
    reset = system.init.on_encoder_reset

    def on_encoder_reset(axis: int, delta: float) -> None:
        shifts[axis] += delta
        reset(axis, delta)
    system.init.on_encoder_reset = on_encoder_reset
    servo, sup = system.servo, system.supervisor
    allowed = [a.max_velocity * TICK * 1.01 + 1e-9 for a in SPEC.axes]
    system.begin(PROGRAM)
    last, last_mode, last_shifts = None, None, list(shifts)
    worst = (0.0, None)
    while not sup.done and system.executive.ticks < 60_000:
        system.executive.step()
        reference, mode = servo.reference, servo.mode
        if last is not None and mode == last_mode and mode in ("trajectory", "initialization", "hold"):
            for i, (r, q, lim) in enumerate(zip(reference, last, allowed)):
                jump = abs(r - (q + shifts[i] - last_shifts[i]))
                if jump > lim and jump / lim > worst[0]:
                    worst = (jump / lim, f"{SPEC.axes[i].name} reference jumps {jump:.4f} deg in 1 ms at "
                                         f"{clock.tick_time:.3f} s ({mode}, {phase_of(system)})")
        last, last_mode, last_shifts = reference, mode, list(shifts)
    summary = system.finish()
    assert clock.stalled_at is not None, f"the phase {phase!r} ended before tick {ticks_in}: no stall"
    assert summary["deadline_misses"] > 0, "the executive did not see the stall"
    assert summary["fault"] is None, f"a {stall:g} s stall in {phase} (tick {ticks_in}) faulted: {summary['fault']}"
    assert worst[1] is None, worst[1]
    assert [s["name"] for s in summary["states"]][-2:] == ["Move Robot", "Stop Robot"]
    assert len(summary["moves"]) == 2


@pytest.mark.parametrize("phase,ticks_in", [
    ("Start Robot", 0), ("Calibrate Offsets", 20), ("sensor", 100), ("index", 30),
    ("start position", 0), ("start position", 100),  # the catch-up overlaps the first move's start
    ("Move Robot", 0), ("Move Robot", 700), ("Stop Robot", 5)])
def test_a_07_s_stall_in_each_phase_never_faults_a_healthy_arm(phase, ticks_in):
    run_with_stall(phase, ticks_in, 0.7)


CASES = st.sampled_from(sorted(PHASES)).flatmap(lambda p: st.tuples(st.just(p), st.integers(0, PHASES[p])))


@settings(max_examples=examples(4), deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(case=CASES, stall=st.floats(0.002, 0.7))
@example(case=("start position", 250), stall=0.7)  # Move Robot begins during the catch-up
def test_any_stall_up_to_07_s_at_any_tick_of_any_phase_never_faults(case, stall):
    phase, ticks_in = case
    run_with_stall(phase, ticks_in, stall)
