"""What a recording costs (``irl run --record``): its size per minute of robot time, the
writer thread's CPU per second of robot time, and the loop's own share (the recording
task's execution time in the tick, as the executive measures it), for the paper's program
and a longer one with a cell; and how many bytes of JSON each topic is before compression.

The writer's CPU is its thread's (time.thread_time around its run); the runs are on the
simulated clock, in this process. Run: .venv/bin/python benchmarks/recording.py
"""
from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from compiler.driver import compile_source  # noqa: E402
from compiler.spec import load_spec  # noqa: E402
from runtime.hardware.backends import load_io_files  # noqa: E402
from runtime.loop.components.recorder import RecordWriter  # noqa: E402
from runtime.loop.system import RobotSystem, RunOptions  # noqa: E402
from runtime.recording import read_messages  # noqa: E402

PROGRAMS = [("programs/test.irl", None), ("programs/pallet_and_glue.irl", "programs/pallet_and_glue.cell.toml")]

_writer_cpu: list[float] = []
_run = RecordWriter.run


def _timed_run(self) -> None:
    start = time.thread_time()
    try:
        _run(self)
    finally:
        _writer_cpu.append(time.thread_time() - start)


RecordWriter.run = _timed_run


def run(path: str, cell: str | None, record: Path) -> dict:
    source = (ROOT / path).read_text(encoding="utf-8")
    result = compile_source(source, str(ROOT / path))
    assert result.ok, result.diagnostics
    spec = load_spec(ROOT / "programs" / "lola15.spc")
    scenario, _ = load_io_files(str(ROOT / cell) if cell else None, None, spec)
    return RobotSystem(spec, RunOptions(record=record, cell=scenario)).run(result.program)


def main() -> int:
    figures = []
    with tempfile.TemporaryDirectory() as directory:
        for path, cell in PROGRAMS:
            record = Path(directory) / (Path(path).stem + ".mcap")
            summary = run(path, cell, record)
            assert summary["fault"] is None and summary["files_error"] is None, summary
            robot = summary["sim_time"]
            size = record.stat().st_size
            writer = _writer_cpu[-1]
            task = summary["deadlines"]["recording"]  # (sampled one tick in eight: its mean)
            _meta, messages, _complete = read_messages(record)
            per_topic: dict[str, int] = {}
            for topic, message in messages:
                per_topic[topic] = per_topic.get(topic, 0) + len(json.dumps(message, separators=(",", ":")))
            figures.append({"program": path, "robot_s": robot, "bytes": size,
                            "bytes_per_min": round(size / robot * 60), "messages": len(messages),
                            "writer_cpu_s": round(writer, 3), "writer_cpu_per_robot_s": round(writer / robot, 5),
                            "loop_cpu_per_robot_s": round(task["runs"] * task["exec_mean_us"] * 1e-6 / robot, 6),
                            "json_bytes_by_topic": per_topic})
    print(json.dumps(figures, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
