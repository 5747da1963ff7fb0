"""The FSM engine's cycle rules, one test per rule of docs/fsm.md (R1 ... R14).

Every test records the programs the engine calls, in order, in a list and asserts the
exact sequence. Then: construction errors, ordered transitions, modes, requests,
sub-machines, diagrams, a property test over random small machines, and tests marked
xfail(strict=True) for rules of runtime/loop/fsm.py that look wrong (each says why in its
reason; they pass the day the engine is changed, and then the mark must go).

No timing here: the cost of a step is measured by benchmarks/fsm_step.py.
"""
from __future__ import annotations

import random
import re
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from runtime.loop.fsm import AUTOMATIC, FSM, REACTIVE, FSMError, State, Transition
from conftest import examples


# ---- helpers -----------------------------------------------------------------------------

def S(name, calls, sub=None, *, prefix=""):
    """A state whose four programs append "<name>.<program>" to ``calls``."""
    tag = prefix + name
    return State(name,
                 entry=lambda: calls.append(f"{tag}.entry"),
                 run=lambda: calls.append(f"{tag}.run"),
                 handle=lambda: calls.append(f"{tag}.handle"),
                 exit=lambda: calls.append(f"{tag}.exit"),
                 sub=sub)


def G(calls, name, value=True):
    """A guard that records "guard <name>" and returns ``value`` (or ``value()``)."""
    def guard():
        calls.append(f"guard {name}")
        return value() if callable(value) else value
    guard.__name__ = name
    return guard


def P(calls, name):
    """A transition program that records "prog <name>"."""
    return lambda: calls.append(f"prog {name}")


def T(calls, source, target, value=True, *, event=None, guard=True, label=""):
    """A recorded transition row: guard "source->target", program "source->target"."""
    name = f"{source}->{target}"
    return Transition(source, target, guard=G(calls, name, value) if guard else None,
                      program=P(calls, name), event=event, label=label)


def machine(calls, names, rows, initial=None, final=None, *, subs=None, mode=AUTOMATIC,
            name="m", prefix="", record_transitions=False):
    subs = subs or {}
    states = [S(n, calls, subs.get(n), prefix=prefix) for n in names]
    on_t = (lambda s, t, now: calls.append(f"on_transition {s}->{t}")) if record_transitions else None
    return FSM(name, states, rows, initial or names[0], final or names[-1], mode=mode,
               on_transition=on_t)


def take(calls):
    """The calls recorded so far, and clear the list."""
    out = list(calls)
    calls.clear()
    return out


# ---- R1: start -----------------------------------------------------------------------------

def test_R1_start_enters_the_initial_state_and_runs_only_its_entry():
    calls = []
    m = machine(calls, ["A", "B", "F"], [T(calls, "A", "B", False)], record_transitions=True)
    assert m.state is None and not m.active
    assert m.step() is False and calls == []          # a step before start does nothing
    m.start()
    assert take(calls) == ["on_transition None->A", "A.entry"]  # no run program at start
    assert m.state == "A" and m.active and not m.finished
    assert m.history == [(0.0, None, "A")]
    m.step()
    assert take(calls) == ["A.run", "guard A->B", "A.handle"]   # the run program's first time


def test_R1_start_drops_events_and_requests_pending_before_it():
    calls = []
    m = machine(calls, ["A", "B", "F"], [T(calls, "A", "B", event="go")])
    m.post("go")
    m.start()
    take(calls)
    m.step()
    assert take(calls) == ["A.run", "A.handle"]        # "go" was posted before start


# ---- R2: the sub-machine steps first ------------------------------------------------------

def test_R2_the_sub_machine_steps_before_the_parent_run_program():
    calls = []
    sub = machine(calls, ["X", "Y"], [T(calls, "X", "Y", False)], name="sub")
    m = machine(calls, ["P", "F"], [T(calls, "P", "F", False)], subs={"P": sub})
    m.start()
    assert take(calls) == ["P.entry", "X.entry"]
    m.step()
    assert take(calls) == ["X.run", "guard X->Y", "X.handle",   # the sub's whole step
                           "P.run", "guard P->F", "P.handle"]   # then the parent's


# ---- R3: the run program runs every step --------------------------------------------------

def test_R3_the_run_program_runs_every_step_even_when_a_transition_fires():
    calls = []
    gate = [False]
    m = machine(calls, ["A", "B", "F"], [T(calls, "A", "B", lambda: gate[0])])
    m.start()
    take(calls)
    for _ in range(2):
        m.step()
    assert take(calls) == ["A.run", "guard A->B", "A.handle"] * 2
    gate[0] = True
    m.step()
    assert take(calls) == ["A.run", "guard A->B", "prog A->B", "A.exit", "B.entry"]


def test_R3_run_comes_before_the_transition_check_in_the_step_that_fires():
    calls = []
    m = machine(calls, ["A", "F"], [T(calls, "A", "F", True)])
    m.start()
    take(calls)
    assert m.step() is True
    assert take(calls)[:2] == ["A.run", "guard A->F"]


# ---- R4: transitions in table order, at most one --------------------------------------------

def test_R4_rows_are_tried_in_table_order_and_the_first_true_guard_wins():
    calls = []
    rows = [T(calls, "A", "B", False), T(calls, "A", "C", True), T(calls, "A", "D", True)]
    m = machine(calls, ["A", "B", "C", "D", "F"], rows)
    m.start()
    take(calls)
    assert m.step() is True
    assert take(calls) == ["A.run", "guard A->B", "guard A->C", "prog A->C", "A.exit", "C.entry"]
    assert m.state == "C"                          # the row to D was never looked at


def test_R4_at_most_one_transition_per_step_even_if_the_target_could_go_on():
    calls = []
    rows = [T(calls, "A", "B"), T(calls, "B", "C"), T(calls, "C", "F")]   # all guards True
    m = machine(calls, ["A", "B", "C", "F"], rows)
    m.start()
    take(calls)
    assert m.step() is True
    assert take(calls) == ["A.run", "guard A->B", "prog A->B", "A.exit", "B.entry"]
    assert m.state == "B"                          # not C, although B->C holds already
    assert m.step() is True and m.state == "C"
    assert m.step() is True and m.state == "F"
    assert [h[1:] for h in m.history] == [(None, "A"), ("A", "B"), ("B", "C"), ("C", "F")]


def test_R4_a_row_without_a_guard_always_holds():
    calls = []
    m = machine(calls, ["A", "F"], [T(calls, "A", "F", guard=False)])
    m.start()
    take(calls)
    assert m.step() is True
    assert take(calls) == ["A.run", "prog A->F", "A.exit", "F.entry"]


def test_R4_an_automatic_row_earlier_in_the_table_beats_a_later_event_row():
    calls = []
    rows = [T(calls, "A", "B", True), T(calls, "A", "C", event="go")]
    m = machine(calls, ["A", "B", "C", "F"], rows)
    m.start()
    m.post("go")
    take(calls)
    m.step()
    assert take(calls) == ["A.run", "guard A->B", "prog A->B", "A.exit", "B.entry"]


# ---- R5: the order of a transition ---------------------------------------------------------

def test_R5_transition_program_then_exit_then_entry():
    calls = []
    m = machine(calls, ["A", "B", "F"], [T(calls, "A", "B")], record_transitions=True)
    m.start()
    take(calls)
    assert m.step() is True
    assert take(calls) == ["A.run", "guard A->B", "prog A->B", "A.exit",
                           "on_transition A->B", "B.entry"]


def test_R5_a_running_sub_machine_is_stopped_before_the_exit_and_the_new_one_starts_after_the_entry():
    calls = []
    sub1 = machine(calls, ["X", "Y"], [T(calls, "X", "Y", False)], name="s1", prefix="s1.")
    sub2 = machine(calls, ["X", "Y"], [T(calls, "X", "Y", False)], name="s2", prefix="s2.")
    m = machine(calls, ["P", "Q", "F"], [T(calls, "P", "Q")], subs={"P": sub1, "Q": sub2})
    m.start()
    assert take(calls) == ["P.entry", "s1.X.entry"]
    m.step()
    assert take(calls) == ["s1.X.run", "guard X->Y", "s1.X.handle",
                           "P.run", "guard P->Q", "prog P->Q",
                           "s1.X.exit", "s1.Y.entry",      # the sub is stopped: to its final state
                           "P.exit", "Q.entry", "s2.X.entry"]
    assert sub1.finished and sub2.state == "X"


def test_R5_a_self_transition_exits_and_re_enters():
    calls = []
    m = machine(calls, ["A", "F"], [T(calls, "A", "A", True)])
    m.start()
    take(calls)
    assert m.step() is True
    assert take(calls) == ["A.run", "guard A->A", "prog A->A", "A.exit", "A.entry"]
    assert m.history[-1][1:] == ("A", "A")


# ---- R6: the new state's run program first runs at the next step ----------------------------

def test_R6_the_target_runs_first_at_the_next_step():
    calls = []
    m = machine(calls, ["A", "B", "F"], [T(calls, "A", "B"), T(calls, "B", "F", False)])
    m.start()
    take(calls)
    m.step()
    assert take(calls) == ["A.run", "guard A->B", "prog A->B", "A.exit", "B.entry"]  # no B.run
    m.step()
    assert take(calls) == ["B.run", "guard B->F", "B.handle"]


# ---- R7: handle only when no transition fired ----------------------------------------------

def test_R7_handle_runs_only_when_no_transition_fired():
    calls = []
    flag = [False]
    m = machine(calls, ["A", "F"], [T(calls, "A", "F", lambda: flag[0])])
    m.start()
    take(calls)
    assert m.step() is False
    assert take(calls) == ["A.run", "guard A->F", "A.handle"]
    flag[0] = True
    assert m.step() is True
    assert take(calls) == ["A.run", "guard A->F", "prog A->F", "A.exit", "F.entry"]  # no handle


def test_R7_handle_runs_when_the_state_has_no_rows_at_all():
    calls = []
    m = machine(calls, ["A", "F"], [])
    m.start()
    take(calls)
    assert m.step() is False
    assert take(calls) == ["A.run", "A.handle"]


# ---- R8: events are consumed at the end of every step ---------------------------------------

def test_R8_an_event_fires_its_row_in_the_next_step():
    calls = []
    m = machine(calls, ["A", "B", "F"], [T(calls, "A", "B", event="go")])
    m.start()
    take(calls)
    m.step()
    assert take(calls) == ["A.run", "A.handle"]           # no event: the guard is not asked
    m.post("go")
    assert m.step() is True
    assert take(calls) == ["A.run", "guard A->B", "prog A->B", "A.exit", "B.entry"]


def test_R8_pending_events_are_cleared_at_the_end_of_the_step_used_or_not():
    calls = []
    gate = [False]
    rows = [T(calls, "A", "B", lambda: gate[0], event="go")]
    m = machine(calls, ["A", "B", "F"], rows)
    m.start()
    take(calls)
    m.post("go")
    m.post("unused")
    m.step()                                               # the guard says no: "go" is lost
    assert take(calls) == ["A.run", "guard A->B", "A.handle"]
    gate[0] = True
    m.step()
    assert take(calls) == ["A.run", "A.handle"]            # not pending any more
    assert m.state == "A"


def test_R8_an_event_posted_by_the_run_program_is_seen_in_the_same_step():
    calls = []
    m = FSM("m", [State("A", run=lambda: (calls.append("A.run"), m.post("go"))), State("F")],
            [T(calls, "A", "F", event="go")], "A", "F")
    m.start()
    assert m.step() is True
    assert calls == ["A.run", "guard A->F", "prog A->F"]


def test_R8_an_event_posted_by_the_sub_machine_is_seen_by_the_parent_in_the_same_step():
    calls = []
    sub = FSM("sub", [State("X", run=lambda: m.post("child done")), State("Y")], [], "X", "Y")
    m = machine(calls, ["P", "F"], [T(calls, "P", "F", event="child done")], subs={"P": sub})
    m.start()
    take(calls)
    assert m.step() is True
    assert take(calls) == ["P.run", "guard P->F", "prog P->F", "P.exit", "F.entry"]


def test_R8_an_event_fires_only_rows_of_the_current_state():
    calls = []
    rows = [T(calls, "A", "B", False), T(calls, "B", "F", event="go")]
    m = machine(calls, ["A", "B", "F"], rows)
    m.start()
    take(calls)
    m.post("go")
    m.step()
    assert take(calls) == ["A.run", "guard A->B", "A.handle"]
    assert m.state == "A"


# ---- R9: automatic and reactive mode --------------------------------------------------------

def test_R9_reactive_mode_ignores_automatic_rows_but_still_runs_and_handles():
    calls = []
    rows = [T(calls, "A", "B", True), T(calls, "A", "C", event="go")]
    m = machine(calls, ["A", "B", "C", "F"], rows, mode=REACTIVE)
    m.start()
    take(calls)
    assert m.step() is False
    assert take(calls) == ["A.run", "A.handle"]             # A->B's guard is not even asked
    m.post("go")
    assert m.step() is True
    assert take(calls) == ["A.run", "guard A->C", "prog A->C", "A.exit", "C.entry"]


def test_R9_modes_switch_at_run_time_and_take_effect_at_the_next_step():
    calls = []
    rows = [T(calls, "A", "B", True), T(calls, "B", "F", True)]
    m = machine(calls, ["A", "B", "F"], rows, mode=REACTIVE)
    m.start()
    take(calls)
    m.step()
    assert take(calls) == ["A.run", "A.handle"] and m.state == "A"
    m.set_mode(AUTOMATIC)
    assert m.mode == AUTOMATIC
    m.step()
    assert take(calls) == ["A.run", "guard A->B", "prog A->B", "A.exit", "B.entry"]
    m.set_mode(REACTIVE)
    m.step()
    assert take(calls) == ["B.run", "B.handle"] and m.state == "B"
    assert m.request_state("F")
    m.step()                                               # a request fires in reactive mode
    assert take(calls) == ["B.run", "guard B->F", "prog B->F", "B.exit", "F.entry"]


def test_R9_set_mode_rejects_an_unknown_mode():
    m = machine([], ["A", "F"], [])
    with pytest.raises(ValueError):
        m.set_mode("manual")
    assert m.mode == AUTOMATIC


def test_R9_events_that_arrive_in_reactive_mode():
    calls = []
    rows = [T(calls, "A", "B", event="go"), T(calls, "B", "F", event="stop")]
    m = machine(calls, ["A", "B", "F"], rows, mode=REACTIVE)
    m.start()
    take(calls)
    m.post("stop")                                  # no row of A listens to it: lost
    m.step()
    assert take(calls) == ["A.run", "A.handle"]
    m.post("go")
    m.post("stop")                                  # both at once: one transition, then both gone
    m.step()
    assert take(calls) == ["A.run", "guard A->B", "prog A->B", "A.exit", "B.entry"]
    m.step()
    assert take(calls) == ["B.run", "B.handle"] and m.state == "B"
    m.post("stop")
    m.step()
    assert take(calls) == ["B.run", "guard B->F", "prog B->F", "B.exit", "F.entry"]
    assert m.finished


# ---- R10: request_state ---------------------------------------------------------------------

def test_R10_a_request_fires_at_the_next_step_through_its_row_and_guard():
    calls = []
    rows = [T(calls, "A", "B", True), T(calls, "A", "C", True)]
    m = machine(calls, ["A", "B", "C", "F"], rows, mode=REACTIVE)
    m.start()
    take(calls)
    assert m.request_state("C") is True
    assert calls == [] and m.state == "A"            # nothing happens until the step
    assert m.step() is True
    assert take(calls) == ["A.run", "guard A->C", "prog A->C", "A.exit", "C.entry"]


def test_R10_request_state_is_false_when_no_row_leads_there():
    calls = []
    rows = [T(calls, "A", "B", False), T(calls, "B", "C", True)]
    m = machine(calls, ["A", "B", "C", "F"], rows)
    assert m.request_state("B") is False             # not started
    m.start()
    assert m.request_state("C") is False             # C is reachable, but not from A
    assert m.request_state("F") is False             # the final state: only by stop()
    assert m.request_state("nowhere") is False
    assert m.request_state("A") is False             # no self-loop row
    take(calls)
    m.step()
    assert take(calls) == ["A.run", "guard A->B", "A.handle"]   # nothing was pending


def test_R10_the_request_is_consumed_by_the_next_step_whether_or_not_its_guard_held():
    calls = []
    gate = [False]
    m = machine(calls, ["A", "B", "F"], [T(calls, "A", "B", lambda: gate[0])], mode=REACTIVE)
    m.start()
    take(calls)
    assert m.request_state("B")
    assert m.step() is False
    assert take(calls) == ["A.run", "guard A->B", "A.handle"]
    gate[0] = True
    assert m.step() is False                          # the request is gone
    assert take(calls) == ["A.run", "A.handle"]


def test_R10_while_a_request_is_pending_only_rows_to_it_are_tried():
    calls = []
    rows = [T(calls, "A", "B", True), T(calls, "A", "C", False, event="go"), T(calls, "A", "C", True)]
    m = machine(calls, ["A", "B", "C", "F"], rows)
    m.start()
    take(calls)
    m.post("go")
    assert m.request_state("C")
    m.step()
    # A->B (automatic, True) is skipped; both rows to C are tried in table order and the
    # event row's event is not needed: a request picks the row by its target only.
    assert take(calls) == ["A.run", "guard A->C", "guard A->C", "prog A->C", "A.exit", "C.entry"]


def test_R10_a_failed_request_blocks_the_automatic_rows_for_that_step():
    calls = []
    rows = [T(calls, "A", "B", True), T(calls, "A", "C", False)]
    m = machine(calls, ["A", "B", "C", "F"], rows)
    m.start()
    take(calls)
    assert m.request_state("C")
    assert m.step() is False
    assert take(calls) == ["A.run", "guard A->C", "A.handle"]
    assert m.step() is True and m.state == "B"        # the next step is automatic again


def test_R10_a_later_request_replaces_an_earlier_one():
    calls = []
    rows = [T(calls, "A", "B"), T(calls, "A", "C")]
    m = machine(calls, ["A", "B", "C", "F"], rows, mode=REACTIVE)
    m.start()
    assert m.request_state("B") and m.request_state("C")
    assert m.request_state("F") is False              # a refused request leaves C pending
    m.step()
    assert m.state == "C"


# ---- R11: stop ------------------------------------------------------------------------------

def test_R11_stop_exits_the_current_state_and_enters_the_final_one_without_a_row():
    calls = []
    m = machine(calls, ["A", "B", "F"], [T(calls, "A", "B")], record_transitions=True)
    m.start()
    m.step()
    take(calls)
    m.stop()
    assert take(calls) == ["B.exit", "on_transition B->F", "F.entry"]   # no run, guard or program
    assert m.finished and m.state == "F"
    assert m.history[-1][1:] == ("B", "F")


def test_R11_stop_stops_a_running_sub_machine_first():
    calls = []
    sub = machine(calls, ["X", "Y"], [T(calls, "X", "Y", False)], prefix="s.")
    m = machine(calls, ["P", "F"], [], subs={"P": sub})
    m.start()
    take(calls)
    m.stop()
    assert take(calls) == ["s.X.exit", "s.Y.entry", "P.exit", "F.entry"]


def test_R11_stop_is_a_no_op_before_start_and_in_the_final_state():
    calls = []
    m = machine(calls, ["A", "F"], [T(calls, "A", "F")])
    m.stop()
    assert calls == [] and m.state is None and m.history == []
    m.start()
    m.step()
    take(calls)
    n = len(m.history)
    m.stop()
    assert calls == [] and len(m.history) == n


def test_R11_stop_from_the_initial_state_right_after_start():
    calls = []
    m = machine(calls, ["A", "B", "F"], [])
    m.start()
    m.stop()
    assert take(calls) == ["A.entry", "A.exit", "F.entry"]


# ---- R12: the final state -------------------------------------------------------------------

def test_R12_the_final_state_is_finished_and_keeps_running():
    calls = []
    m = machine(calls, ["A", "F"], [T(calls, "A", "F")])
    m.start()
    m.step()
    take(calls)
    assert m.finished
    for _ in range(3):
        assert m.step() is False
    assert take(calls) == ["F.run", "F.handle"] * 3
    assert m.finished


def test_R12_rows_out_of_the_final_state_are_evaluated_and_leave_it():
    calls = []
    m = machine(calls, ["A", "F"], [T(calls, "F", "A", True)])
    m.start()
    m.stop()
    take(calls)
    assert m.step() is True
    assert take(calls) == ["F.run", "guard F->A", "prog F->A", "F.exit", "A.entry"]
    assert not m.finished and m.state == "A"


# ---- R13: hierarchical states ---------------------------------------------------------------

def _sub_done_after(calls, n, prefix="s."):
    """A sub-machine X -> Y (final) that finishes at its ``n``-th step."""
    count = [0]

    def ready():
        count[0] += 1
        return count[0] >= n
    ready.__name__ = "ready"
    rows = [Transition("X", "Y", guard=ready, program=lambda: calls.append("prog X->Y"))]
    return FSM("sub", [S("X", calls, prefix=prefix), S("Y", calls, prefix=prefix)], rows, "X", "Y")


def test_R13_the_sub_machine_is_entered_with_its_parent_and_stepped_with_it():
    calls = []
    sub = _sub_done_after(calls, 2)
    m = machine(calls, ["A", "P", "F"], [T(calls, "A", "P")], subs={"P": sub})
    m.start()
    assert sub.state is None                                # not before its parent is entered
    m.step()
    assert take(calls) == ["A.entry", "A.run", "guard A->P", "prog A->P", "A.exit", "P.entry",
                           "s.X.entry"]
    m.step()
    assert take(calls) == ["s.X.run", "s.X.handle", "P.run", "P.handle"]
    assert m.path() == "P/X"


def test_R13_the_parent_leaves_in_the_step_its_sub_machine_finishes():
    calls = []
    sub = _sub_done_after(calls, 2)
    rows = [Transition("P", "F", guard=G(calls, "sub done", lambda: sub.finished),
                       program=P(calls, "P->F"))]
    m = machine(calls, ["P", "F"], rows, subs={"P": sub})
    m.start()
    m.step()
    take(calls)
    assert m.step() is True
    assert take(calls) == ["s.X.run", "prog X->Y", "s.X.exit", "s.Y.entry",   # the sub finishes
                           "P.run", "guard sub done",                          # the parent sees it
                           "prog P->F", "P.exit", "F.entry"]                   # a finished sub is not stopped


def test_R13_a_finished_sub_machine_is_no_longer_stepped():
    calls = []
    sub = _sub_done_after(calls, 1)
    m = machine(calls, ["P", "F"], [], subs={"P": sub})
    m.start()
    m.step()
    take(calls)
    assert sub.finished and m.path() == "P"
    m.step()
    assert take(calls) == ["P.run", "P.handle"]            # no s.Y.run


def test_R13_the_sub_machine_is_stopped_when_the_parent_exits_early_and_restarts_on_re_entry():
    calls = []
    sub = _sub_done_after(calls, 100)
    rows = [T(calls, "P", "Q", event="abort"), T(calls, "Q", "P", event="retry")]
    m = machine(calls, ["P", "Q", "F"], rows, subs={"P": sub})
    m.start()
    m.step()
    take(calls)
    m.post("abort")
    m.step()
    assert take(calls) == ["s.X.run", "s.X.handle", "P.run", "guard P->Q", "prog P->Q",
                           "s.X.exit", "s.Y.entry", "P.exit", "Q.entry"]
    assert sub.finished
    m.post("retry")
    m.step()
    assert take(calls) == ["Q.run", "guard Q->P", "prog Q->P", "Q.exit", "P.entry", "s.Y.exit", "s.X.entry"]
    assert sub.state == "X" and m.path() == "P/X"


def test_R13_path_shows_parent_and_child_at_every_depth():
    calls = []
    inner = FSM("inner", [State("Find Sensor A1"), State("Done")], [], "Find Sensor A1", "Done")
    middle = FSM("middle", [State("Init", sub=inner), State("End")], [], "Init", "End")
    m = FSM("top", [State("Initialization Sequence", sub=middle), State("Stop")], [],
            "Initialization Sequence", "Stop")
    assert m.path() == ""
    m.start()
    assert m.path() == "Initialization Sequence/Init/Find Sensor A1"
    inner.stop()
    assert m.path() == "Initialization Sequence/Init"
    m.stop()
    assert m.path() == "Stop"
    assert calls == []


# ---- R14: history and on_transition ---------------------------------------------------------

def test_R14_history_records_every_entry_with_the_clock_and_on_transition_sees_it_first():
    calls = []
    now = [0.0]
    seen = []

    def on_transition(source, target, t):
        seen.append((t, source, target))
        calls.append(f"on_transition {source}->{target}")
    m = FSM("m", [S("A", calls), S("B", calls), S("F", calls)], [T(calls, "A", "B")], "A", "F",
            clock=lambda: now[0], on_transition=on_transition)
    now[0] = 1.0
    m.start()
    now[0] = 2.0
    m.step()
    now[0] = 3.0
    m.step()                                               # no transition: no record
    now[0] = 4.0
    m.stop()
    assert m.history == seen == [(1.0, None, "A"), (2.0, "A", "B"), (4.0, "B", "F")]
    assert calls == ["on_transition None->A", "A.entry",
                     "A.run", "guard A->B", "prog A->B", "A.exit", "on_transition A->B", "B.entry",
                     "B.run", "B.handle",
                     "B.exit", "on_transition B->F", "F.entry"]


def test_R14_history_is_kept_across_a_restart():
    m = machine([], ["A", "F"], [])
    m.start()
    m.stop()
    m.start()
    assert [h[1:] for h in m.history] == [(None, "A"), ("A", "F"), (None, "A")]


# ---- the worked example of docs/fsm.md ------------------------------------------------------

def test_worked_example_of_the_docs():
    calls = []
    work_runs = [0]

    def work_run():
        calls.append("Work.run")
        work_runs[0] += 1

    states = [S("Idle", calls), State("Work", entry=lambda: calls.append("Work.entry"), run=work_run,
                                      handle=lambda: calls.append("Work.handle"),
                                      exit=lambda: calls.append("Work.exit")), S("Done", calls)]
    rows = [Transition("Idle", "Work"),
            Transition("Work", "Done", guard=lambda: work_runs[0] >= 2,
                       program=lambda: calls.append("prog Work->Done"))]
    m = FSM("example", states, rows, "Idle", "Done")
    m.start()
    table = [("start", take(calls), m.state)]
    for i in range(1, 6):
        m.step()
        table.append((f"step {i}", take(calls), m.state))
    assert table == [
        ("start", ["Idle.entry"], "Idle"),
        ("step 1", ["Idle.run", "Idle.exit", "Work.entry"], "Work"),
        ("step 2", ["Work.run", "Work.handle"], "Work"),
        ("step 3", ["Work.run", "prog Work->Done", "Work.exit", "Done.entry"], "Done"),
        ("step 4", ["Done.run", "Done.handle"], "Done"),
        ("step 5", ["Done.run", "Done.handle"], "Done"),
    ]
    assert m.history == [(0.0, None, "Idle"), (0.0, "Idle", "Work"), (0.0, "Work", "Done")]


def test_every_rule_of_the_docs_has_a_test_and_every_rule_test_a_rule():
    text = (Path(__file__).resolve().parents[1] / "docs" / "fsm.md").read_text(encoding="utf-8")
    documented = {int(n) for n in re.findall(r"^\*\*R(\d+) —", text, re.M)}
    tested = {int(n) for n in re.findall(r"^def test_R(\d+)_", Path(__file__).read_text(encoding="utf-8"),
                                         re.M)}
    assert documented == set(range(1, len(documented) + 1)), documented
    assert documented == tested


# ---- construction errors --------------------------------------------------------------------

@pytest.mark.parametrize("states, rows, initial, final, mode, words", [
    (["A", "A", "F"], [], "A", "F", AUTOMATIC, "same name"),
    (["A", "F"], [("A", "Z")], "A", "F", AUTOMATIC, "unknown state"),
    (["A", "F"], [("Z", "A")], "A", "F", AUTOMATIC, "unknown state"),
    (["A", "F"], [], "Z", "F", AUTOMATIC, "initial"),
    (["A", "F"], [], "A", "Z", AUTOMATIC, "final"),
    (["A", "F"], [], "A", "A", AUTOMATIC, "must differ"),
    (["A", "F"], [], "A", "F", "manual", "mode"),
], ids=["duplicate state", "unknown target", "unknown source", "missing initial",
        "missing final", "initial is final", "bad mode"])
def test_construction_errors_raise_FSMError(states, rows, initial, final, mode, words):
    with pytest.raises(FSMError, match=words):
        FSM("bad", [State(n) for n in states], [Transition(s, t) for s, t in rows], initial, final,
            mode=mode)


def test_no_program_runs_while_building():
    calls = []
    machine(calls, ["A", "B", "F"], [T(calls, "A", "B")], subs={"A": machine(calls, ["X", "Y"], [])})
    assert calls == []


# ---- diagrams -------------------------------------------------------------------------------

def _diagram_machine():
    sub = FSM("sub", [State("Find Sensor"), State("Find Z"), State("Go Home")],
              [Transition("Find Sensor", "Find Z", label="sensor touched"),
               Transition("Find Z", "Go Home", label="z found")], "Find Sensor", "Go Home")

    def calibrated():
        return True
    states = [State("Start Robot"), State("Calibrate Offsets"), State("Initialization Sequence", sub=sub),
              State("Move Robot"), State("Stop Robot")]
    rows = [Transition("Start Robot", "Calibrate Offsets", label="not calibrated"),
            Transition("Start Robot", "Move Robot", guard=calibrated),
            Transition("Calibrate Offsets", "Initialization Sequence", event="calibrated"),
            Transition("Initialization Sequence", "Move Robot", label="initialized"),
            Transition("Move Robot", "Stop Robot", label="motions done")]
    m = FSM("Viewer", states, rows, "Start Robot", "Stop Robot")
    labels = ["not calibrated", "calibrated", "on calibrated", "initialized", "motions done",
              "sensor touched", "z found"]
    return m, labels


def test_to_mermaid_contains_every_state_and_transition_label():
    m, labels = _diagram_machine()
    text = m.to_mermaid()
    assert text.startswith("stateDiagram-v2\n")
    for s in m.states:
        assert f"{s.name.replace(' ', '_')} : {s.name}" in text, s.name
    for s in m.states[2].sub.states:        # inside the parent's block, by id (see the xfail)
        assert s.name.replace(" ", "_") in text, s.name
    assert "state Initialization_Sequence {" in text
    for label in labels:
        assert label in text, label
    assert "[*] --> Start_Robot" in text and "Stop_Robot --> [*]" in text
    assert "Start_Robot --> Move_Robot : calibrated" in text
    assert "Calibrate_Offsets --> Initialization_Sequence : on calibrated" in text


def test_to_dot_contains_every_state_and_transition_label():
    m, labels = _diagram_machine()
    text = m.to_dot()
    assert text.startswith('digraph "Viewer" {') and text.rstrip().endswith("}")
    for s in m.states + m.states[2].sub.states:
        assert s.name in text, s.name
    for t in m.transitions:
        assert f'"{t.source}" -> "{t.target}"' in text
    for label in labels[:5]:                 # the top-level rows; the sub-machine's states are in
        assert f'label="{label}"' in text    # its parent's box (its rows are not drawn in DOT)
    assert '"Stop Robot" [peripheries=2]' in text
    assert '__start -> "Start Robot"' in text


# ---- property test over random small machines ------------------------------------------------

@st.composite
def random_machines(draw):
    n = draw(st.integers(2, 6))
    names = [f"S{i}" for i in range(n)]
    initial = draw(st.sampled_from(names))
    final = draw(st.sampled_from([x for x in names if x != initial]))
    guard = st.sampled_from([None, 0.1, 0.3, 0.5, 0.8, 1.0, "sub"])
    rows = draw(st.lists(st.tuples(st.sampled_from(names), st.sampled_from(names), guard,
                                   st.sampled_from([None, None, "e1", "e2"])),
                         min_size=n, max_size=3 * n))
    host = draw(st.one_of(st.none(), st.sampled_from(names)))
    mode = draw(st.sampled_from([AUTOMATIC, REACTIVE]))
    actions = draw(st.lists(st.sampled_from(["step"] * 6 + ["post e1", "post e2", "request",
                                                            "mode", "stop sub"]),
                            min_size=10, max_size=60))
    seed = draw(st.integers(0, 2**32 - 1))
    return names, initial, final, rows, host, mode, actions, seed


def _alternates(seq):
    """entry, exit, entry, exit, ... (a trailing entry is the state still active)."""
    return all(kind == ("entry" if i % 2 == 0 else "exit") for i, kind in enumerate(seq))


@settings(derandomize=True, deadline=None, max_examples=examples(300))
@given(random_machines())
def test_property_random_machines_keep_the_invariants(spec):
    names, initial, final, rows, host, mode, actions, seed = spec
    rng = random.Random(seed)
    log = []          # ("top"|"sub", state, program)
    programs = []     # transition programs of the top machine, per step

    def state(level, name, sub=None):
        return State(name, entry=lambda: log.append((level, name, "entry")),
                     run=lambda: log.append((level, name, "run")),
                     handle=lambda: log.append((level, name, "handle")),
                     exit=lambda: log.append((level, name, "exit")), sub=sub)

    sub = None
    if host is not None:
        sub = FSM("sub", [state("sub", "X"), state("sub", "Z"), state("sub", "Y")],
                  [Transition("X", "Z", guard=lambda: rng.random() < 0.5),
                   Transition("Z", "Y", guard=lambda: rng.random() < 0.5),
                   Transition("X", "Y", event="e1")], "X", "Y")

    def make_guard(p):
        if p is None:
            return None
        if p == "sub":
            return lambda: sub is not None and sub.finished
        return lambda: rng.random() < p

    table = [Transition(s, t, guard=make_guard(p), event=e, program=lambda: programs.append(1))
             for s, t, p, e in rows]
    m = FSM("rand", [state("top", n, sub if n == host else None) for n in names], table,
            initial, final, mode=mode)

    def inside_top():
        inside = set()
        for level, name, kind in log:
            if level == "top" and kind == "entry":
                inside.add(name)
            elif level == "top" and kind == "exit":
                assert name in inside, f"{name} exited without being entered"
                inside.discard(name)
        return inside

    m.start()
    assert m.state == initial and m.history[-1][1:] == (None, initial)
    assert inside_top() == {initial}                     # exactly one current state
    for action in actions:
        before_history, before_programs = len(m.history), len(programs)
        before_log = len(log)
        if action == "step":
            fired = m.step()
            grew = len(m.history) - before_history
            assert grew <= 1                                   # at most one transition per step
            assert grew == (1 if fired else 0)
            assert len(programs) - before_programs == grew
            entries = [e for e in log[before_log:] if e[0] == "top" and e[2] == "entry"]
            assert len(entries) == grew
            runs = [e for e in log[before_log:] if e[0] == "top" and e[2] == "run"]
            assert len(runs) == 1                              # the run program, once, every step
        elif action.startswith("post"):
            m.post(action.split()[1])
        elif action == "request":
            target = rng.choice(names)
            ok = m.request_state(target)
            assert ok == any(t.source == m.state and t.target == target for t in table)
        elif action == "mode":
            m.set_mode(REACTIVE if m.mode == AUTOMATIC else AUTOMATIC)
        elif action == "stop sub" and sub is not None and sub.active:
            sub.stop()
            assert sub.finished
        assert m.state in names
        assert inside_top() == {m.state}                       # exactly one current state
        if sub is not None and m.state == host:
            assert sub.state in ("X", "Y", "Z")
    # entry and exit alternate per state (the sub's final state is left out: a finished
    # sub-machine is restarted without its final state's exit, see the xfail below)
    for level, name in {(lv, n) for lv, n, _ in log}:
        if (level, name) == ("sub", "Y"):
            continue
        kinds = [k for lv, n, k in log if (lv, n) == (level, name) and k in ("entry", "exit")]
        assert _alternates(kinds), (level, name, kinds)
    was = m.state
    m.stop()
    assert m.finished and m.state == final
    if was != final:
        assert m.history[-1][1:] == (was, final)
    assert inside_top() == {final}
    if sub is not None:
        assert not sub.active or sub.finished or m.state == host


# ---- rules that were wrong in runtime/loop/fsm.py, fixed; kept as regression tests ------------------

def test_fixed_an_event_posted_by_an_entry_program_reaches_the_next_step():
    calls = []
    m = FSM("m", [State("A"), State("B", entry=lambda: m.post("arrived")), State("F")],
            [Transition("A", "B"), T(calls, "B", "F", event="arrived")], "A", "F")
    m.start()
    m.step()                        # A -> B; B's entry posts "arrived"
    assert m.state == "B"
    assert m.step() is True and m.state == "F"


def test_fixed_start_on_a_running_machine_exits_the_current_state():
    calls = []
    m = machine(calls, ["A", "B", "F"], [T(calls, "A", "B")])
    m.start()
    m.step()
    take(calls)
    try:
        m.start()
    except FSMError:
        return
    assert calls[:1] == ["B.exit"], calls


def test_fixed_a_sub_machine_restart_exits_its_final_state():
    calls = []
    sub = _sub_done_after(calls, 1)
    rows = [Transition("P", "Q", guard=lambda: sub.finished), Transition("Q", "P")]
    m = machine(calls, ["P", "Q", "F"], rows, subs={"P": sub})
    m.start()
    for _ in range(2):              # the sub finishes and P -> Q (R13); Q -> P (the sub restarts)
        m.step()
    sub_calls = [c for c in calls if c.startswith("s.") and c.endswith(("entry", "exit"))]
    assert sub_calls == ["s.X.entry", "s.X.exit", "s.Y.entry", "s.Y.exit", "s.X.entry"], sub_calls


def test_fixed_stop_drops_a_pending_request():
    calls = []
    rows = [T(calls, "A", "B"), T(calls, "F", "B", event="restart")]
    m = machine(calls, ["A", "B", "F"], rows, mode=REACTIVE)
    m.start()
    assert m.request_state("B")
    m.stop()
    m.step()
    assert m.finished, m.state


def test_fixed_to_dot_shows_a_state_without_rows():
    m = FSM("m", [State("A"), State("Orphan"), State("F")], [Transition("A", "F")], "A", "F")
    assert "Orphan" in m.to_dot()


def test_fixed_to_mermaid_labels_sub_machine_event_rows():
    sub = FSM("sub", [State("X"), State("Y")], [Transition("X", "Y", event="found")], "X", "Y")
    m = FSM("m", [State("P", sub=sub), State("F")], [Transition("P", "F", event="done")], "P", "F")
    text = m.to_mermaid()
    assert "P --> F : on done" in text
    assert "X --> Y : on found" in text


def test_fixed_to_mermaid_names_sub_machine_states():
    sub = FSM("sub", [State("Find Sensor"), State("Go Home")], [Transition("Find Sensor", "Go Home")],
              "Find Sensor", "Go Home")
    m = FSM("m", [State("Init", sub=sub), State("F")], [Transition("Init", "F")], "Init", "F")
    text = m.to_mermaid()
    assert "Find_Sensor : Find Sensor" in text
