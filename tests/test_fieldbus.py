"""The robot's I/O on a PLC over Modbus TCP (issue 16): `irl serve --fieldbus FILE`
against pymodbus's own server on loopback, with a little PLC logic beside it. A program
that talks to the PLC runs to completion; the PLC's loss stops the robot (category 1)
and faults the program, within the configured timeout."""
from __future__ import annotations

import asyncio
import contextlib
import logging
import statistics
import threading
import time
from pathlib import Path

import pytest

from runtime.hardware.backends import FieldbusError, load_fieldbus, parse_fieldbus
from runtime.hardware.fieldbus import ModbusIo, parse_modbus

from conftest import ROOT, SPEC_PATH, SPEC
COILS, DISCRETE, HOLDING, INPUT_REGISTERS = 1, 2, 3, 4  # Modbus function codes: read coils, discrete inputs, ...


class Plc:
    """pymodbus's TCP server with one device (64 coils, 64 discrete inputs, 16 holding and 16
    input registers) on loopback, in a thread of its own; ``coils``/``set_input``,
    ``holding``/``set_register`` reach its data as the PLC's own program would."""

    def __init__(self, port: int):
        from pymodbus.server import ModbusTcpServer
        from pymodbus.simulator import DataType, SimData, SimDevice

        logging.getLogger("pymodbus").setLevel(logging.CRITICAL)
        bits = lambda: [SimData(0, count=64, values=False, datatype=DataType.BITS)]  # noqa: E731
        words = lambda: [SimData(0, count=16, values=0, datatype=DataType.REGISTERS)]  # noqa: E731
        device = SimDevice(1, simdata=(bits(), bits(), words(), words()))
        self.port = port
        self.loop = asyncio.new_event_loop()
        started = threading.Event()
        self.server = None
        #: a misbehaving PLC: pdu -> the reply it sends instead (None: the right one)
        self.misreply = None

        def trace(sending: bool, pdu):
            changed = self.misreply(pdu) if sending and self.misreply is not None else None
            return pdu if changed is None else changed

        async def main():
            self.server = ModbusTcpServer(device, address=("127.0.0.1", port), trace_pdu=trace)
            started.set()
            await self.server.serve_forever()
        self.thread = threading.Thread(target=lambda: self.loop.run_until_complete(main()), daemon=True)
        self.thread.start()
        started.wait(10)

    def _run(self, coroutine):
        return asyncio.run_coroutine_threadsafe(coroutine, self.loop).result(5)

    def coils(self, count: int = 16) -> list[bool]:
        return [bool(v) for v in self._run(self.server.async_getValues(1, COILS, 0, count))]

    def set_input(self, n: int, value: bool) -> None:
        """Discrete input of the robot's in[n] (address n - 1)."""
        self._run(self.server.async_setValues(1, DISCRETE, n - 1, [value]))

    def holding(self, count: int = 4) -> list[int]:
        return list(self._run(self.server.async_getValues(1, HOLDING, 0, count)))

    def set_register(self, address: int, raw: int) -> None:
        """Input register ``address`` (what an analog input module puts there)."""
        self._run(self.server.async_setValues(1, INPUT_REGISTERS, address, [raw]))

    def stop(self) -> None:
        if self.server is not None:
            self._run(self.server.shutdown())
            self.server = None


def fieldbus_file(directory: Path, port: int, timeout: float = 0.5) -> Path:
    path = directory / "plc.toml"
    path.write_text(f'[modbus]\nhost = "127.0.0.1"\nport = {port}\ndevice = 1\ninputs = 0\noutputs = 0\n'
                    f"poll = 0.005\ntimeout = {timeout}\n", encoding="utf-8")
    return path


def program(body: str, variables: str = "") -> bytes:
    from compiler.driver import compile_source
    from compiler.objcode import encode

    result = compile_source(f'program p;\nsystem_specification "{SPEC_PATH}";\n{variables}seq\n{body}endseq\n'
                            "endprogram;\n", "p.irl")
    assert result.ok, result.diagnostics
    return encode(result.program)


@pytest.mark.parametrize("text, words", [
    ("[modbus]\nport = 502\n", "[modbus] host is missing"),
    ('[modbus]\nhost = "plc"\nport = 70000\n', "[modbus] port: expected an integer 1..65535, got 70000"),
    ('[modbus]\nhost = "plc"\npoll = 0\n', "[modbus] poll: expected a number of seconds 0.001..1, got 0"),
    ('[modbus]\nhost = "plc"\ntimeot = 1\n', "unknown 'timeot' (did you mean 'timeout'?)"),
    ('[modbus]\nhost = "plc"\ninputs = 65530\n', "must fit below address 65536"),
    ('[profinet]\nhost = "plc"\n', "unknown table [profinet]"),
])
def test_a_bad_fieldbus_file_says_where_and_what_is_allowed(tmp_path, text, words):
    path = tmp_path / "plc.toml"
    path.write_text(text, encoding="utf-8")
    with pytest.raises(FieldbusError, match=None) as error:
        load_fieldbus(path, SPEC)
    assert words in str(error.value), str(error.value)


@contextlib.contextmanager
def plc_and_exchange(timeout: float, spec=SPEC, **fields):
    """A real PLC on a free port and the exchange thread (ModbusIo) connected to it, polling
    every 5 ms with this timeout (and ``fields`` of [modbus]); both closed afterwards."""
    from conftest import free_port

    port = free_port()
    plc = Plc(port)
    io = ModbusIo(parse_modbus({"host": "127.0.0.1", "port": port, "poll": 0.005, "timeout": timeout} | fields, spec),
                  spec.inputs, spec.outputs, spec.analog_inputs, spec.analog_outputs)
    io.start()
    try:
        assert io.wait_connected(5.0), io.lost()
        yield plc, io
    finally:
        io.close()
        plc.stop()


def test_the_io_follows_the_plc_and_a_lost_plc_is_said_within_its_timeout(tmp_path):
    """The exchange thread alone: inputs read, outputs written, and `lost` once no
    exchange has succeeded for `timeout` s."""
    with plc_and_exchange(timeout=0.3) as (plc, io):
        plc.set_input(3, True)
        io.set_output(2, True)
        deadline = time.monotonic() + 5.0
        while not (io.input(3) and plc.coils()[1]):
            assert time.monotonic() < deadline, (io.inputs, plc.coils())
            time.sleep(0.005)
        plc.stop()
        lost_at = time.monotonic()
        while io.lost() is None:
            assert time.monotonic() - lost_at < 5.0
            time.sleep(0.005)
        assert "no exchange with the PLC at 127.0.0.1" in io.lost() and "the limit is 0.3 s" in io.lost()


def test_irl_serve_runs_a_program_against_a_plc_and_stops_the_robot_when_the_plc_is_lost(tmp_path):
    from conftest import ServerProcess, free_port, wait_end, wait_for

    port = free_port()
    plc = Plc(port)
    stop = threading.Event()
    reactions: list[float] = []

    def logic() -> None:
        """The PLC's program: the gripper (in[2] follows out[1] after 20 ms), and the
        reaction test on in[3] -> out[3]."""
        while not stop.is_set():
            coils = plc.coils()
            plc.set_input(2, coils[0])
            time.sleep(0.02)

    server = ServerProcess(tmp_path / "server", tmp_path / "state", sim_clock=False,
                           extra=("--fieldbus", fieldbus_file(tmp_path, port), "--deadline-policy", "soft")).start()
    thread = threading.Thread(target=logic, daemon=True)
    thread.start()
    try:
        client = server.client(timeout=30.0)
        gripper = program("  out[1] := true;\n  wait for in[2] timeout 5 sec;\n  print \"closed\";\n"
                          "  out[1] := false;\n  wait for not in[2] timeout 5 sec;\n  print \"opened\";\n"
                          "  for i := 1 to 20 do\n    wait for in[3] timeout 5 sec;\n    out[3] := true;\n"
                          "    wait for not in[3] timeout 5 sec;\n    out[3] := false;\n  endfor;\n",
                          "var i : integer;\n")
        job = client.request("submit", {"object": gripper})["program"]
        wait_for(client, job, lambda s: s.get("line") is not None and s["line"] >= 11, "at its reaction loop",
                 server)
        for _ in range(20):  # input change -> the program's reaction, as the PLC sees it
            started = time.monotonic()
            plc.set_input(3, True)
            while not plc.coils()[2]:
                assert time.monotonic() - started < 5.0
                time.sleep(0.0005)
            reactions.append(time.monotonic() - started)
            plc.set_input(3, False)
            while plc.coils()[2]:
                assert time.monotonic() - started < 10.0
                time.sleep(0.0005)
        final = wait_end(client, job, server)
        assert final["state"] == "completed", final
        log = [entry["text"] for entry in final["summary"]["log"]]
        assert log == ["closed", "opened"], log
        header = Path(final["report"]).read_text().splitlines()[0]
        assert header.endswith(",out_16")

        waiting = client.request("submit", {"object": program("  wait for in[5] timeout 60 sec;\n")})["program"]
        wait_for(client, waiting, lambda s: s.get("fsm") == "Move Robot", "waiting in Move Robot", server)
        stop.set()
        thread.join(5)
        plc.stop()
        lost = time.monotonic()
        final = wait_end(client, waiting, server)
        took = time.monotonic() - lost
        assert final["state"] == "faulted" and "the fieldbus is lost" in final["fault"], final
        assert final["summary"]["stop"]["category"] == 1, final["summary"]["stop"]
        assert took < 10.0, took
        ms = sorted(1000 * r for r in reactions)
        print(f"PLC input -> program -> PLC output, {len(ms)} reactions: p50 {statistics.median(ms):.1f} ms, "
              f"max {ms[-1]:.1f} ms (poll 5 ms); PLC lost -> program faulted in {took:.2f} s (timeout 0.5 s)")
        assert client.request("status")["loop_gone"] is None
    finally:
        stop.set()
        plc.stop()
        assert server.stop() == 0, server.log()


@pytest.mark.long
def test_the_pick_and_place_program_runs_its_cell_over_modbus(tmp_path):
    """programs/pick_place.irl itself under `irl run --realtime --fieldbus`, against a PLC
    that plays its cell (docs/runtime.md): the feeder has a part, the fixture is free, the
    jaw sensors follow the gripper's outputs after 0.3 s; at the first machine start the
    operator presses stop (in[16]), so the program ends its loop as it would in the cell,
    after one part (about 15 s of wall clock) instead of ten. (The loop's later rounds are
    the same exchanges; tests/test_cell.py runs all ten on the simulated clock.)"""
    import csv
    import json
    import subprocess

    from conftest import IRL, free_port, realtime_share

    port = free_port()
    plc = Plc(port)
    stop = threading.Event()
    starts: list[float] = []

    def cell() -> None:
        plc.set_input(1, True)  # a part at the feeder
        plc.set_input(4, True)  # the fixture free
        jaws = {2: (0, False, 0.0), 3: (1, False, 0.0)}  # input -> (coil it follows, last coil value, since)
        cycle_start = False
        while not stop.is_set():
            coils, now = plc.coils(), time.monotonic()
            for sensor, (coil, value, since) in list(jaws.items()):
                if coils[coil] != value:
                    jaws[sensor] = (coil, coils[coil], now)
                elif now - since >= 0.3:
                    plc.set_input(sensor, value)
            if coils[3] and not cycle_start:
                starts.append(now)
                if len(starts) == 1:
                    plc.set_input(16, True)  # the operator's stop button
            cycle_start = coils[3]
            time.sleep(0.005)

    thread = threading.Thread(target=cell, daemon=True)
    thread.start()
    report = tmp_path / "pick_place.csv"
    try:
        with realtime_share():  # (a SCHED_FIFO loop: its share of the machine's real-time capacity)
            proc = subprocess.run([*IRL, "run", ROOT / "programs" / "pick_place.irl", "--realtime", "--fieldbus",
                                   fieldbus_file(tmp_path, port), "--deadline-policy", "soft", "--report", report,
                                   "--json", "--state-dir", tmp_path / "state"],
                                  cwd=ROOT, capture_output=True, text=True, timeout=240)
        summary = json.loads(proc.stdout)
        assert proc.returncode == 0 and summary["fault"] is None, (proc.stdout, proc.stderr)
        assert [entry["text"].split(" in ")[0] for entry in summary["log"]] == ["part 1 of 10 loaded"]
        assert len(starts) == 1
        with open(report, newline="") as f:
            rows = list(csv.DictReader(f))
        assert rows[-1]["in_16"] == "1" and rows[0]["in_16"] == "0"
        assert any(r["out_4"] == "1" for r in rows) and any(r["in_2"] == "1" for r in rows)
    finally:
        stop.set()
        thread.join(5)
        plc.stop()


def no_inputs(pdu):
    """A PLC's reply to reading the discrete inputs that holds none of them."""
    from pymodbus.pdu.bit_message import ReadDiscreteInputsResponse

    if pdu.function_code == DISCRETE:
        return ReadDiscreteInputsResponse(dev_id=pdu.dev_id, transaction_id=pdu.transaction_id, bits=[])
    return None


def test_a_plc_reply_without_the_inputs_is_a_failed_exchange_and_the_io_keeps_its_inputs():
    """Issue 26, fault 1, at the exchange: a reply that does not hold every input asked for
    is not taken (the inputs keep their number and last values); it fails the exchange,
    which says what was wrong, and the PLC is lost after its timeout."""
    with plc_and_exchange(timeout=0.2) as (plc, io):
        plc.set_input(2, True)
        deadline = time.monotonic() + 5.0
        while not io.input(2):
            assert time.monotonic() < deadline
            time.sleep(0.005)
        plc.misreply = no_inputs
        while io.lost() is None:
            assert len(io.inputs) == SPEC.inputs and io.inputs[1], io.inputs
            assert time.monotonic() < deadline + 5.0, "a PLC that answers without the inputs is never lost"
            time.sleep(0.005)
        assert len(io.inputs) == SPEC.inputs and io.inputs[1]
        why = io.lost()
        assert f"held 0 of the {SPEC.inputs} inputs asked for" in why, why
        plc.misreply = None  # the PLC mended: the exchanges succeed again
        while io.lost() is not None:
            assert time.monotonic() < deadline + 10.0, io.lost()
            time.sleep(0.005)


def test_a_plc_that_answers_without_the_inputs_stops_the_robot_with_complete_files(tmp_path):
    """Issue 26, fault 1, whole: a program with an interrupt on an input, on the wall clock
    against a real pymodbus PLC that starts answering without the inputs. The program
    faults with the fieldbus lost (said in the robot's terms), the robot stops at rest,
    and the report and its states file are complete to the end of Stop Robot."""
    import csv
    import io as io_

    from runtime.loop.system import RobotSystem, RunOptions

    from conftest import free_port

    port = free_port()
    plc = Plc(port)
    plc.set_input(5, True)  # the light curtain whole
    config = parse_fieldbus({"modbus": {"host": "127.0.0.1", "port": port, "poll": 0.005, "timeout": 0.2}}, SPEC)
    report = tmp_path / "report.csv"
    system = RobotSystem(SPEC, RunOptions(realtime=True, fieldbus=config, report=report, deadline_policy="soft"))
    system.memory.calibrated = True  # skip calibration and homing: a short wall-clock run
    system.memory.compensation = [0.0] * len(SPEC.axes)
    system.memory.initialized = True
    system.memory.encoder_offsets = [0.0] * len(SPEC.axes)
    from compiler.driver import compile_source

    source = (f'program p;\nsystem_specification "{SPEC_PATH}";\n'
              "interrupt curtain when not in[5] priority 1 stop then resume;\n"
              'seq\n  print "curtain";\nendseq\nendinterrupt;\n'
              'seq\n  enable curtain;\n  out[1] := true;\n  wait for in[2] timeout 10 sec;\n  print "done";\nendseq\n'
              "endprogram;\n")
    result = compile_source(source, "p.irl", SPEC_PATH)
    assert result.ok, result.diagnostics
    try:
        system.begin(result.program, report)
        ex = system.executive
        while system.trajectory.line != 11 and not system.supervisor.done:  # waiting for in[2]
            ex.step()
        plc.misreply = no_inputs
        while not system.supervisor.done:
            ex.step()
        summary = system.finish()
    finally:
        system.io.close()
        plc.stop()
    fault = summary["fault"]
    assert fault is not None and "the fieldbus is lost" in fault and "inputs asked for" in fault, fault
    assert "index" not in fault and "Error" not in fault, fault
    assert summary["stop"]["category"] == 1, summary["stop"]
    assert summary["log"] == [], summary["log"]
    assert summary.get("files_error") is None, summary
    rows = list(csv.reader(io_.StringIO(report.read_text(encoding="utf-8"))))
    header = rows[0]
    assert all(len(row) == len(header) for row in rows[1:]), "rows of another width"
    assert rows[-1][1] == "Stop Robot", rows[-1]
    velocities = [i for i, name in enumerate(header) if name.startswith("out_vel_")]
    assert all(float(rows[-1][i]) == 0.0 for i in velocities), rows[-1]
    transitions = report.with_suffix(".states.csv").read_text(encoding="utf-8").splitlines()
    assert transitions[-1].endswith(",Move Robot,Stop Robot"), transitions


def test_the_plc_io_numbers_its_inputs_and_outputs_from_1_and_says_which_exist():
    """ModbusIo's I/O is the DigitalIo the simulated arm's is: in[0] is no input (it read
    the last one, as a Python index, before they shared it)."""
    io = ModbusIo(parse_modbus({"host": "plc"}, SPEC), SPEC.inputs, SPEC.outputs)
    for bad in (0, SPEC.inputs + 1):
        with pytest.raises(IndexError, match=rf"^digital input {bad} does not exist: the robot on the PLC at "
                                             rf"plc:502 has inputs 1\.\.{SPEC.inputs}$"):
            io.input(bad)
    with pytest.raises(IndexError, match=r"^digital output 0 does not exist"):
        io.set_output(0, True)
    io.set_output(SPEC.outputs, True)
    assert io.outputs[-1] and io.output(SPEC.outputs) and not io.input(1)
    with pytest.raises(PermissionError):
        io.set_input(1, True)


def _until(condition, what: str, seconds: float = 5.0) -> None:
    deadline = time.monotonic() + seconds
    while not condition():
        assert time.monotonic() < deadline, what
        time.sleep(0.005)


def test_analog_channels_and_groups_over_modbus_registers():
    """Issue 33 item 4 over a real PLC: an analog input is an input register scaled to its
    channel's range (0 its low end, analog_counts its high end), an analog output a holding
    register; a reading beyond the high end is beyond the channel's range (the program's io
    error when it reads it: runtime.loop.components.trajectory); a group of outputs is
    sent in one exchange."""
    from compiler.spec import load_spec

    cell = load_spec(ROOT / "programs" / "lola15_cell.spc")  # part height 0..100 mm, glue pressure 0..6 bar
    with plc_and_exchange(0.5, cell, analog_inputs=2, analog_outputs=1, analog_counts=27648) as (plc, io):
        plc.set_register(2, 13824)  # the middle of the channel
        _until(lambda: io.analog_input(1) == pytest.approx(50.0), "the analog input never followed the PLC")
        plc.set_register(2, 32767)  # a Siemens module's overflow: beyond the channel's range
        _until(lambda: io.analog_input(1) > 100.0, "an overflowing register was not taken as it reads")
        assert cell.analog_inputs[0].problem(1, io.analog_input(1)) is not None
        io.set_analog_output(1, 4.5)
        _until(lambda: plc.holding(2)[1] == round(4.5 / 6.0 * 27648), "the analog output never reached the PLC")
        assert io.analog_output(1) == 4.5
        writes = io.exchanges
        io.set_outputs(3, [True, False, True, True])
        _until(lambda: plc.coils(8)[2:6] == [True, False, True, True], "the group never reached the PLC")
        assert io.exchanges > writes


def test_an_analog_channel_the_fieldbus_does_not_map_says_so():
    from compiler.spec import load_spec

    cell = load_spec(ROOT / "programs" / "lola15_cell.spc")
    with plc_and_exchange(0.5, cell) as (plc, io):
        with pytest.raises(IndexError, match=r"analog input 1 is not on the PLC: its fieldbus file maps no analog "
                                             r"inputs \(analog_inputs in \[modbus\]\)"):
            io.analog_input(1)
        with pytest.raises(IndexError, match="analog output 1 is not on the PLC"):
            io.set_analog_output(1, 2.0)


def test_a_plc_reply_without_the_registers_is_a_failed_exchange():
    from compiler.spec import load_spec
    from pymodbus.pdu.register_message import ReadInputRegistersResponse

    cell = load_spec(ROOT / "programs" / "lola15_cell.spc")

    def no_registers(pdu):
        if pdu.function_code == INPUT_REGISTERS:
            return ReadInputRegistersResponse(dev_id=pdu.dev_id, transaction_id=pdu.transaction_id, registers=[])
        return None
    with plc_and_exchange(0.2, cell, analog_inputs=0) as (plc, io):
        plc.misreply = no_registers
        _until(lambda: io.lost() is not None, "a PLC that answers without the registers is never lost")
        assert "held 0 registers for the 1 analog inputs asked for" in io.lost(), io.lost()
