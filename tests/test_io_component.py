"""The digital I/O as a component (runtime/loop/components/io.py): ``io``, in the lifecycle like
the others, with ``inputs`` and ``outputs`` ports, one sense task (the cell, the inputs, the
backend's health), and its backends behind one interface (the simulated robot's own I/O,
a PLC's: tests/test_fieldbus.py)."""
from __future__ import annotations


import pytest

from compiler.driver import compile_source
from compiler.objcode import encode
from runtime.hardware.sim.cell import parse_scenario
from runtime.hardware.sim.robot import SimRobot
from runtime.loop.system import RobotSystem, RunOptions
from runtime.timing import TICK

from conftest import SPEC_PATH, SPEC


def program(body: str, decls: str = ""):
    result = compile_source(f'program p;\nsystem_specification "{SPEC_PATH}";\n{decls}seq\n{body}endseq\n'
                            "endprogram;\n", "p.irl", SPEC_PATH)
    assert result.ok, result.diagnostics
    return result.program


def cycle(system: RobotSystem, prog, after_tick=None, ticks: int = 200_000, report=None) -> dict:
    """One cycle, tick by tick; ``after_tick(k, now)`` after each (now: that tick's time)."""
    system.begin(prog, report)
    for _ in range(ticks):
        if system.supervisor.done:
            break
        k = system.executive.ticks
        system.executive.step()
        if after_tick is not None:
            after_tick(k, k * TICK)
    assert system.supervisor.done, "the cycle did not end"
    return system.finish()


def test_the_io_component_is_listed_with_its_lifecycle_and_keeps_its_scripting_interface(tmp_path):
    """`components` lists io with a lifecycle state (stopped between programs, running in
    one); `help io`, `io.inputs`, `io.in[n]` and the forcing of an input are as before."""
    from runtime.server.server import ServeOptions, Server

    source = (f'program w;\nsystem_specification "{SPEC_PATH}";\nseq\n'
              '  wait for in[5] timeout 30 sec;\n  print "released";\nendseq\nendprogram;\n')
    result = compile_source(source, "w.irl")
    assert result.ok, result.diagnostics
    server = Server(SPEC, ServeOptions(sim_clock=True, state_dir=tmp_path / "state", loop_process=False))

    def lifecycle() -> str:
        lines = server.request("call", {"text": "components"})["output"].splitlines()
        return next(line.split()[1] for line in lines if line.split()[0] == "io")
    try:
        assert "io" in server.request("call", {"text": "components"})["value"]
        assert lifecycle() == "stopped"
        described = server.request("call", {"text": "help io"})["output"]
        assert described.startswith("io (stopped)\n")
        assert described.rstrip().endswith("operations:")  # no operations: the system drives its lifecycle
        job = server.request("submit", {"object": encode(result.program)})["program"]
        while not (server.jobs.current is not None and server.system.trajectory.line == 4):
            server.turn(idle_wait=False)
        assert lifecycle() == "running"
        assert server.request("call", {"text": "io.inputs"})["value"] == [False] * SPEC.inputs
        assert server.request("call", {"text": "io.in[5] = true"})["value"] is True
        assert server.request("call", {"text": "io.in[5]"})["value"] is True  # the port, at once
        assert server.system.io.inputs.value[4] is True
        assert server.request("status")["inputs"][4] is True
        while server.jobs.current is not None:
            server.turn(idle_wait=False)
        assert [e["text"] for e in server.jobs[job].summary["log"]] == ["released"]
        assert lifecycle() == "stopped"
        # between programs (no tick): a forced input is in the port, and the status, at once
        assert server.request("call", {"text": "io.in[7] = true"})["value"] is True
        assert server.system.io.inputs.value[6] is True and server.request("status")["inputs"][6] is True
        assert server.request("call", {"text": "io.in[7]"})["value"] is True
    finally:
        server.close()


def test_the_ports_carry_what_the_scenario_sets_at_the_tick_its_rule_says():
    """A follower (in[5] copies out[1] 50 ms later), a timeline (in[6] toggles 0.25 s after
    the program began: its first step in Move Robot): after each tick the ``inputs`` port is what
    the cell set in that very tick (stamped with it), the ``outputs`` port what the program set."""
    delay_ticks = 50
    scenario = parse_scenario({"follow": [{"input": 5, "output": 1, "delay": delay_ticks * TICK}],
                               "timeline": [{"input": 6, "at": [0.25]}], "inputs": {"1": True}}, SPEC)
    system = RobotSystem(SPEC, RunOptions(cell=scenario))
    io = system.io
    assert io.inputs.value[0] is True and len(io.inputs.value) == SPEC.inputs  # idle: the cell as it stands
    seen: list = []

    def after_tick(k, now):
        assert io.inputs.value == system.backend.inputs and io.inputs.stamp == now
        assert io.outputs.value == system.backend.outputs
        seen.append((k, io.inputs.value[4], io.inputs.value[5], io.outputs.value[0], io.outputs.stamp))
    summary = cycle(system, program('  out[1] := true;\n  wait for in[5] timeout 5 sec;\n  print "seen";\n'
                                    '  wait for in[6] timeout 5 sec;\n'), after_tick)
    assert summary["fault"] is None and [e["text"] for e in summary["log"]] == ["seen"]
    out_k = next(k for k, _, _, out1, _ in seen if out1)
    in5_k = next(k for k, in5, _, _, _ in seen if in5)
    assert in5_k == out_k + 1 + delay_ticks  # the cell sees the edge on the next tick, then the delay
    in6_k = next(k for k, _, in6, _, _ in seen if in6)
    start_k = round(system.trajectory.started_at / TICK)  # the program's first step (its timelines count from it)
    assert in6_k == start_k + round(0.25 / TICK)


def test_an_output_set_by_the_program_is_in_the_port_and_the_backend_in_the_same_tick():
    system = RobotSystem(SPEC, RunOptions())
    io, backend = system.io, system.backend
    rises: list = []

    def after_tick(k, now):
        assert io.outputs.value == backend.outputs, k  # never a tick apart
        if io.outputs.value[2] and not rises:
            rises.append((k, now, io.outputs.stamp, backend.output(3)))
    summary = cycle(system, program("  out[3] := true;\n  out[4] := true;\n  out[4] := false;\n"), after_tick)
    assert summary["fault"] is None
    (k, now, stamp, in_backend), = rises
    assert stamp == now and in_backend
    assert io.outputs.value[2:4] == (True, False) and backend.outputs[2:4] == (True, False)


class LosingRobot(SimRobot):
    """A hardware-like backend with its own I/O that can be lost (``why``)."""

    def __init__(self, spec, seed: int = 0):
        super().__init__(spec, seed)
        self.why: str | None = None
        self.asked = 0

    def lost(self):
        self.asked += 1
        return self.why


def test_a_backend_that_is_lost_stops_the_robot_category_1_once_and_faults_the_program():
    backend = LosingRobot(SPEC)
    system = RobotSystem(SPEC, RunOptions(), backend=backend)
    stops: list = []
    request_stop = system.supervisor.request_stop

    def counted(reason="stopped by the operator", emergency=False):
        stops.append((reason, emergency))
        request_stop(reason, emergency)
    system.supervisor.request_stop = counted

    def after_tick(k, now):
        if backend.why is None and system.trajectory.line == 4:  # waiting for in[5], in Move Robot
            backend.why = "no exchange with the PLC at plc:502 (device 1) for 0.51 s, the limit is 0.5 s"
    summary = cycle(system, program('  wait for in[5] timeout 5 sec;\n  print "not lost";\n'), after_tick)
    text = "the fieldbus is lost: no exchange with the PLC at plc:502 (device 1) for 0.51 s, the limit is 0.5 s"
    assert summary["fault"] is not None and text in summary["fault"], summary["fault"]
    assert summary["stop"] == {"category": 1, "reason": text}
    assert stops == [(text, True)]  # once, although the backend stayed lost for every later tick
    assert backend.asked > 10 and summary["log"] == []
    # the next cycle takes a loss anew; a healthy backend runs the program through
    backend.why = None
    stops.clear()
    summary = cycle(system, program('  print "fine";\n'))
    assert summary["fault"] is None and [e["text"] for e in summary["log"]] == ["fine"] and stops == []


def test_a_hardware_backend_without_io_still_runs_a_program_without_io():
    class Hardware:
        """A hardware-like robot backend that has no digital I/O (not an IoBackend)."""

        def __init__(self, robot):
            self._robot = robot

        def __getattr__(self, name):  # the robot's own interface, as a driver would give it
            if name in ("inputs", "outputs", "input", "set_output"):
                raise AttributeError(name)
            return getattr(self._robot, name)

    system = RobotSystem(SPEC, RunOptions(), backend=Hardware(SimRobot(SPEC)))
    summary = cycle(system, program('  print "no io";\n'))
    assert summary["fault"] is None and [e["text"] for e in summary["log"]] == ["no io"]
    assert system.io.inputs.value == () and system.io.outputs.value == ()


def test_the_io_task_is_the_first_of_the_tick():
    system = RobotSystem(SPEC, RunOptions())
    names = [t.name for t in system.executive.tasks]
    assert names[0] == "io" and "cell" not in names and "fieldbus" not in names
    assert system.executive.tasks[0].component is system.io and system.executive.tasks[0].phase == "sense"


def test_a_plc_that_cannot_be_reached_refuses_the_program_at_begin(tmp_path):
    """The PLC's ModbusIo is the component's backend: opened when the system is built,
    a program refused at ``begin`` while it cannot be reached, with the reason."""
    from conftest import free_port

    from runtime.hardware.backends import parse_fieldbus
    from runtime.hardware.fieldbus import ModbusIo

    port = free_port()  # nothing listens there
    config = parse_fieldbus({"modbus": {"host": "127.0.0.1", "port": port, "poll": 0.005, "timeout": 0.05}}, SPEC)
    system = RobotSystem(SPEC, RunOptions(realtime=True, fieldbus=config, state_dir=tmp_path / "state"))
    try:
        assert isinstance(system.io.backend, ModbusIo) and system.io.backend._thread is not None
        assert "io" in system.report.columns
        with pytest.raises(ValueError, match=rf"^the program cannot start: no exchange with the PLC at "
                                             rf"127\.0\.0\.1:{port} \(device 1\) ever, the limit is 0\.05 s"):
            system.begin(program('  print "never";\n'))
    finally:
        system.io.close()


class ShrinkingRobot(SimRobot):
    """A backend whose inputs lose their number (``short``: it gives none)."""

    def __init__(self, spec, seed: int = 0):
        super().__init__(spec, seed)
        self.short = False

    @property
    def inputs(self):
        return () if self.short else super().inputs


def test_inputs_of_another_number_are_not_taken_and_stop_the_robot_with_complete_files(tmp_path):
    """Issue 26, fault 1, for any backend: inputs that are not the robot's number are not
    put in the port (it keeps the last ones, of the right number); the robot stops
    (category 1) with the reason in the robot's terms, the report keeps every row to the
    end of Stop Robot, and the summary says no file was left incomplete."""
    import csv
    import io as io_

    backend = ShrinkingRobot(SPEC)
    backend.set_input(5, True)
    report = tmp_path / "r.csv"
    system = RobotSystem(SPEC, RunOptions(), backend=backend)
    system.report.columns.append("io")
    prog = program("  enable curtain;\n  wait for in[2] timeout 5 sec;\n  print \"done\";\n",
                   "interrupt curtain when not in[5] priority 1 stop then resume;\nseq\n  print \"curtain\";\n"
                   "endseq\nendinterrupt;\n")
    widths = set()

    def after_tick(k, now):
        widths.add(len(system.io.inputs.value))
        if system.trajectory.line == 10 and not backend.short:  # waiting for in[2], in Move Robot
            backend.short = True
    summary = cycle(system, prog, after_tick, report=report)
    assert widths == {SPEC.inputs}
    text = f"the I/O is not trusted: it gave 0 inputs, the robot has {SPEC.inputs}"
    assert summary["fault"] is not None and text in summary["fault"], summary["fault"]
    assert summary["stop"] == {"category": 1, "reason": text} and summary["log"] == []
    assert summary["files_error"] is None
    rows = list(csv.reader(io_.StringIO(report.read_text(encoding="utf-8"))))
    assert all(len(row) == len(rows[0]) for row in rows) and rows[-1][1] == "Stop Robot", rows[-1]
    assert report.with_suffix(".states.csv").read_text().splitlines()[-1].endswith(",Move Robot,Stop Robot")
