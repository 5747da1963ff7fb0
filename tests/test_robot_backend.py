"""The robot's backends behind declared interfaces (runtime/hardware/interface.py): the loop
asks of a robot backend only what :class:`RobotBackend` declares, of an I/O backend only
what :class:`IoBackend` declares; a second robot backend, declared in
runtime/hardware/backends.py's table, runs a program with nothing else changed."""
from __future__ import annotations

import ast
import math
from pathlib import Path

import pytest

from compiler.driver import compile_source
from runtime.hardware import backends, interface
from runtime.hardware.interface import IoBackend, RobotBackend
from runtime.hardware.sim.robot import SimRobot
from runtime.loop.system import RobotSystem, RunOptions

from conftest import ROOT, SPEC, SPEC_PATH

LOOP = ROOT / "runtime" / "loop"


def _interface_of(annotation: ast.expr | None) -> type | None:
    """The interface class of runtime.hardware.interface an annotation names, or None."""
    for node in ast.walk(annotation) if annotation is not None else ():
        if isinstance(node, ast.Name) and isinstance(getattr(interface, node.id, None), type):
            return getattr(interface, node.id)
    return None


def backend_uses(root: Path = LOOP) -> list[tuple[str, int, type | None, str]]:
    """Every use of a backend in the loop's classes: (file, line, its interface, the name
    used). A class's backend is its ``backend`` attribute (``self.backend``, or a local
    ``backend`` it was read into); its interface is the annotation of the ``backend``
    parameter of the class's ``__init__``."""
    uses = []
    for path in sorted(root.rglob("*.py")):
        tree = ast.parse(path.read_text(encoding="utf-8"))
        for cls in (n for n in ast.walk(tree) if isinstance(n, ast.ClassDef)):
            declared = None
            for item in cls.body:
                if isinstance(item, ast.FunctionDef) and item.name == "__init__":
                    args = item.args.args + item.args.kwonlyargs
                    declared = next((_interface_of(a.annotation) for a in args if a.arg == "backend"), None)
            for node in ast.walk(cls):
                if not isinstance(node, ast.Attribute):
                    continue
                target = node.value
                own = (isinstance(target, ast.Attribute) and target.attr == "backend"
                       and isinstance(target.value, ast.Name) and target.value.id == "self")
                local = isinstance(target, ast.Name) and target.id == "backend"
                if own or local:
                    uses.append((str(path.relative_to(root)), node.lineno, declared, node.attr))
    return uses


def test_the_loop_uses_of_each_backend_only_what_its_interface_declares():
    """An AST scan of runtime/loop: every ``backend.NAME`` is declared by the interface
    the class's ``backend`` parameter is annotated with (a method left out of the interface,
    or a backend without an annotation, fails here)."""
    uses = backend_uses()
    assert {u[2] for u in uses} == {RobotBackend, IoBackend}, "the scan no longer finds both backends"
    robot = {name for _f, _l, kind, name in uses if kind is RobotBackend}
    assert {"read", "read_counts", "step", "brakes_released", "apply_brakes", "disable_drives"} <= robot
    undeclared = [f"{f}:{line}: backend.{name} is not declared by {kind.__name__ if kind else 'any interface'}"
                  for f, line, kind, name in uses if kind is None or not hasattr(kind, name)]
    assert not undeclared, "\n".join(undeclared)


def test_the_scan_fails_on_a_method_the_interface_does_not_declare(tmp_path):
    (tmp_path / "component.py").write_text(
        "from runtime.hardware.interface import RobotBackend\n"
        "class C:\n"
        "    def __init__(self, backend: RobotBackend):\n        self.backend = backend\n"
        "    def tick(self):\n        self.backend.read()\n        self.backend.warp_speed()\n", encoding="utf-8")
    assert [(kind, name) for _f, _l, kind, name in backend_uses(tmp_path)] == [
        (RobotBackend, "read"), (RobotBackend, "warp_speed")]
    assert not hasattr(RobotBackend, "warp_speed")


def test_the_simulated_arm_implements_every_method_of_the_robot_interface():
    declared = {name for name, value in vars(RobotBackend).items() if callable(value) and not name.startswith("_")}
    for name in declared - {"inject"}:
        assert getattr(SimRobot, name) is not getattr(RobotBackend, name), f"SimRobot does not implement {name}"


class IdealArm(RobotBackend):
    """A second robot backend, as small as one can be: drives that move at exactly the
    commanded velocity, brakes and safe torque off that act at once, incremental encoders
    counting from the park position (home), index pulses at ``k * index_spacing``, homing
    sensors at ``sensor_position +- sensor_window``. No digital I/O (not an IoBackend)."""

    def __init__(self, spec, seed: int = 0):
        self.axes = spec.axes
        self.x = [a.home for a in spec.axes]
        self.origin = tuple(self.x)
        self.events = [0] * len(self.x)
        self.latched = [0] * len(self.x)
        self.braked = True
        self.enabled = True
        self.steps = 0

    def _count(self, i: int, x: float) -> int:
        return math.floor((x - self.origin[i]) * self.axes[i].counts_per_unit)

    def read_counts(self):
        return tuple(self._count(i, x) for i, x in enumerate(self.x))

    def read(self):
        sensors = tuple(abs(x - a.sensor_position) <= a.sensor_window for x, a in zip(self.x, self.axes))
        return self.read_counts(), tuple(self.events), tuple(self.latched), sensors

    def step(self, dt, velocity_commands):
        self.steps += 1
        if self.braked or not self.enabled:
            return
        for i, (axis, v) in enumerate(zip(self.axes, velocity_commands)):
            old, new = self.x[i], self.x[i] + v * dt
            spacing = axis.index_spacing
            r_old, r_new = math.floor(old / spacing), math.floor(new / spacing)
            if r_new != r_old:
                self.events[i] += abs(r_new - r_old)
                self.latched[i] = self._count(i, (max(r_new, r_old)) * spacing)
            self.x[i] = new

    def release_brakes(self):
        self.braked = False

    def apply_brakes(self):
        self.braked = True

    def brakes_released(self):
        return not self.braked

    def brakes_applied(self):
        return self.braked

    def disable_drives(self):
        self.enabled = False

    def enable_drives(self):
        self.enabled = True

    def drives_enabled(self):
        return self.enabled


def test_a_second_robot_backend_in_the_table_runs_a_program(monkeypatch, tmp_path):
    """An entry in runtime.hardware.backends.ROBOTS is all a second backend needs: the
    robot system makes it by name, calibrates and homes it and runs the program on it."""
    made = []

    def make(spec, seed):
        made.append(IdealArm(spec, seed))
        return made[-1]

    monkeypatch.setitem(backends.ROBOTS, "ideal", backends.RobotKind("a test's ideal arm", make))
    source = (f'program p;\nsystem_specification "{SPEC_PATH}";\nseq\n  print "on the ideal arm";\n'
              "endseq\nendprogram;\n")
    result = compile_source(source, "p.irl", SPEC_PATH)
    assert result.ok, result.diagnostics
    system = RobotSystem(SPEC, RunOptions(robot="ideal", state_dir=tmp_path, max_time=60.0))
    assert system.backend is made[0] and system.state_file.identity["backend"] == "ideal"
    summary = system.run(result.program)
    assert summary["fault"] is None, summary["fault"]
    assert [e["text"] for e in summary["log"]] == ["on the ideal arm"]
    assert system.memory.initialized and made[0].steps >= summary["ticks"] - 1  # homed on it, every tick commanded
    assert system.io.inputs.value == ()  # no digital I/O of its own


def test_an_unknown_robot_backend_or_an_uninjectable_fault_is_refused_clearly():
    with pytest.raises(ValueError, match=r"^unknown robot backend 'warp': expected one of sim"):
        RobotSystem(SPEC, RunOptions(robot="warp"))
    with pytest.raises(ValueError, match=r"no injectable faults"):
        IdealArm(SPEC).inject("sensor_dead", 0)
