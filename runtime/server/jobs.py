"""The server's programs (docs/protocol.md, ``submit``, ``status``, ``wait``): the job
table, the queue, the running job, the finished ones kept for status, and the ``wait``
requests not yet answered.

Not real-time: this runs in the server's process; a job is started by a command to the
loop (runtime.server.looplink) and ends with the loop's summary of it.
"""
from __future__ import annotations

import collections
import logging
import time
from pathlib import Path

from compiler.objcode import MOVE_CODES, OP, Program

from runtime.recording import recording_name
from runtime.server.looplink import LoopCommand, LoopLink
from runtime.wire import messages, protocol
from runtime.wire.protocol import JobState, ProtocolError

log = logging.getLogger("irl.serve")

HISTORY = 200  # finished programs kept for status


class Job:
    """One submitted program and what became of it."""

    def __init__(self, job_id: int, name: str, program: Program | None, report: Path | None,
                 settings: dict | None = None, configuration: str | None = None, record: Path | None = None):
        self.id = job_id
        self.name = name
        self.program = program
        self.report = report
        self.record = record  # its recording (irl serve --record DIR), or None
        self.settings = settings  # a reconfiguration (no program): the settings to apply
        self.configuration = configuration
        self.state = JobState.QUEUED
        self.fault: str | None = None
        self.submitted = time.time()
        self.started: float | None = None
        self.ended: float | None = None
        self.summary: dict | None = None
        self.moves_total = moves_total(program) if program is not None else 0
        self.object: bytes | None = None  # the verified object code, for the loop
        self.source: str | None = None  # the source text it was submitted with (the source op)
        self.jog = False  # a jog session (runtime/loop/jogging.py), started by a jog request
        self.step = False  # in step mode (runtime/loop/stepping.py)
        self.from_line: int | None = None  # from the move on this line

    def as_dict(self, summary: bool = True) -> dict:
        d = {"id": self.id, "name": self.name, "state": self.state, "fault": self.fault,
             "submitted": self.submitted, "started": self.started, "ended": self.ended,
             "report": str(self.report) if self.report else None,
             "record": str(self.record) if self.record else None, "moves_total": self.moves_total,
             "kind": "jog" if self.jog else "program" if self.settings is None else "reconfiguration",
             "step": self.step, "from_line": self.from_line}
        if self.summary is not None:
            d.update(line=None, moves_done=sum(1 for m in self.summary["moves"] if m["actual_duration"] is not None))
            if summary:
                d["summary"] = self.summary
        return d


def moves_total(program: Program, from_line: int | None = None) -> int | None:
    """How many moves the program makes (from the move on line ``from_line``), when that
    is known without running it (no loops, no procedure calls); else None."""
    moves = 0
    started = from_line is None
    for offset, instr in enumerate(program.code):
        op = instr[0]
        if op in MOVE_CODES:
            started = started or program.starts_at(offset, from_line)
            moves += started
        elif op == OP.CALL or (op in (OP.JUMP, OP.JUMP_IF_FALSE) and instr[1] <= offset):
            return None
    return moves


class Wait:
    """What ``op_wait`` returns: answer when ``program`` has ended, or at ``deadline``."""

    __slots__ = ("program", "deadline")

    def __init__(self, program: int, deadline: float):
        self.program = program
        self.deadline = deadline


class Jobs:
    """The programs and reconfigurations submitted, by id (``jobs[id]``, ``id in jobs``,
    iterating gives the ids kept), the queue of those waiting, the running one
    (``current``) and the ``wait`` requests. ``publish(message)`` says a job's changes on
    telemetry, ``reply(identity, reply)`` answers a wait. With ``record_dir`` every program
    is recorded there, its file named by ``session``, its id and its name
    (runtime.recording.recording_name)."""

    def __init__(self, report_dir: Path, link: LoopLink, publish, reply, record_dir: Path | None = None,
                 session: str = ""):
        self.table: dict[int, Job] = {}
        self.queue: collections.deque[Job] = collections.deque()
        self.finished: collections.deque[int] = collections.deque()
        self.current: Job | None = None
        self.next_id = 1
        self.waiters: list = []  # (Wait, identity, request id, version) of unanswered waits
        self.report_dir = report_dir
        self.record_dir = record_dir
        self.session = session
        self.link = link
        self.publish = publish
        self.reply = reply

    def __getitem__(self, job_id: int) -> Job:
        return self.table[job_id]

    def __contains__(self, job_id) -> bool:
        return job_id in self.table

    def __iter__(self):
        return iter(self.table)

    def get(self, job_id) -> Job | None:
        return self.table.get(job_id)

    def recent(self) -> list[dict]:
        """The last 20 jobs but the running one, as status lists them."""
        return [job.as_dict(summary=False) for job in list(self.table.values())[-21:]
                if job.state != JobState.RUNNING][-20:]

    # ---- submitting ------------------------------------------------------------------------
    def check_room(self) -> None:
        """Refuse (``queue_full``) a program or reconfiguration beyond MAX_QUEUED waiting
        ones (the running one does not count)."""
        if len(self.queue) >= protocol.MAX_QUEUED:
            raise ProtocolError("queue_full", f"the queue is full: it holds {len(self.queue)} programs waiting to "
                                              f"run, at most {protocol.MAX_QUEUED} may wait; submit again when "
                                              "one has started (or abort queued ones)")

    def submit(self, name: str, program: Program, data: bytes, step: bool = False,
               from_line: int | None = None) -> Job:
        """Queue a verified program (``data``: its object code), in step mode (``step``),
        from the move on line ``from_line`` (checked by the caller)."""
        record = self.record_dir / recording_name(self.session, self.next_id, name) if self.record_dir else None
        job = Job(self.next_id, name, program, self.report_dir / f"program-{self.next_id}.csv", record=record)
        job.object = data
        job.step, job.from_line = step, from_line
        if from_line is not None:
            job.moves_total = moves_total(program, from_line)
        self._queue(job)
        log.info("program %d (%s) queued", job.id, name)
        return job

    def reconfigure(self, name: str, settings: dict) -> Job:
        """Queue a Robot Reconfiguration cycle to the configuration ``name``."""
        job = Job(self.next_id, f"reconfigure {name}", None, None, settings=settings, configuration=name)
        self._queue(job)
        return job

    def start_jog(self, override: float) -> Job:
        """Start a jog session on the loop at once (the robot idle, the queue empty)."""
        job = Job(self.next_id, "jog", None, self.report_dir / f"program-{self.next_id}.csv")
        job.jog = True
        self.next_id += 1
        self.table[job.id] = job
        self._run(job, override)
        return job

    def _queue(self, job: Job) -> None:
        self.next_id += 1
        self.table[job.id] = job
        self.queue.append(job)

    # ---- running ---------------------------------------------------------------------------
    def start_next(self, override: float) -> None:
        """Start the first job of the queue on the loop, at ``override`` percent."""
        self._run(self.queue.popleft(), override)

    def _run(self, job: Job, override: float) -> None:
        """Start ``job`` on the loop, at ``override`` percent."""
        for directory in (self.report_dir, job.record.parent if job.record else None):
            try:
                if directory is not None:
                    directory.mkdir(parents=True, exist_ok=True)
            except OSError as exc:
                self.end(job, JobState.FAULTED, f"cannot make {directory}: {exc.strerror or exc}")
                return
        job.state, job.started = JobState.RUNNING, time.time()
        self.current = job
        log.info("program %d (%s) started", job.id, job.name)

        def started(result: dict) -> dict:
            self.publish({"kind": "event", "event": "program", "program": job.id, "state": JobState.RUNNING,
                          "t": result["t"]})
            return result

        def refused(reply: dict) -> None:  # the program cannot run here
            self.end(job, JobState.FAULTED, reply["message"])

        self.link.send(LoopCommand(messages.Start(job.id, job.object, str(job.report) if job.report else None,
                                                  job.settings, override, str(job.record) if job.record else None,
                                                  job.jog, job.step, job.from_line),
                                   finish=started, failed=refused))

    def finish(self, message: dict, completed) -> None:
        """The loop's summary of the running job (``message``): it has ended;
        ``completed(job)`` is called first when it ended without a fault."""
        job = self.current
        if job is None or job.id != message["job"]:
            return
        job.summary = message["summary"]
        fault = job.summary["fault"]
        if fault is None:
            completed(job)
        self.end(job, JobState.COMPLETED if fault is None else JobState.ABORTED if message["aborted"]
                 else JobState.FAULTED, fault)

    def end(self, job: Job, state: JobState, fault: str | None) -> None:
        """A program has ended (``completed``, ``faulted``, ``aborted``) or will never run
        (``cancelled``): kept for status, said on telemetry, its waiters answered."""
        job.state, job.fault, job.ended = state, fault, time.time()
        if job is self.current:
            self.current = None
        self._retire(job)
        log.info("program %d %s%s", job.id, state, f": {fault}" if fault else "")
        self.publish({"kind": "event", "event": "program", "program": job.id, "state": state, "fault": fault})
        self.answer_waiters()

    def _retire(self, job: Job) -> None:
        job.program = job.object = None  # the code is not needed any more
        self.finished.append(job.id)
        while len(self.finished) > HISTORY:
            self.table.pop(self.finished.popleft(), None)

    def cancel_queue(self, reason: str) -> list[int]:
        """Cancel every job waiting; returns their ids."""
        cancelled = []
        while self.queue:
            job = self.queue.popleft()
            self.end(job, JobState.CANCELLED, reason)
            cancelled.append(job.id)
        return cancelled

    def cancel(self, wanted: int) -> dict:
        """Remove a job from the queue (the operator's abort of a job not running)."""
        for job in self.queue:
            if job.id == wanted:
                self.queue.remove(job)
                self.end(job, JobState.CANCELLED, "removed from the queue by the operator")
                return {"program": wanted, "state": JobState.CANCELLED}
        job = self.table.get(wanted)
        if job is not None:
            raise ProtocolError("refused", f"program {wanted} has already ended ({job.state})")
        raise ProtocolError("not_found", f"program {wanted} is neither running nor queued (no such program)")

    def fail(self, reason: str) -> None:
        """The loop is gone: the running program faulted, the waiting ones cancelled."""
        if self.current is not None:
            self.end(self.current, JobState.FAULTED, reason)
        self.cancel_queue(reason)

    # ---- reading ---------------------------------------------------------------------------
    def running(self, job: Job) -> dict:
        """A running job as status shows it (from the loop's latest snapshot)."""
        snap = self.link.snapshot
        d = job.as_dict()
        if snap.job == job.id and snap.progress is not None:
            progress = snap.progress
            d.update(line=progress.line, moves_done=progress.moves_done, paused=progress.paused, fsm=snap.state,
                     waiting_for_step=progress.waiting_for_step, approach=progress.approach)
        else:  # started, the loop's first snapshot of it not yet here
            d.update(line=None, moves_done=0, paused=False, fsm="Start Robot", waiting_for_step=False,
                     approach=False)
        return d

    def status(self, job_id) -> dict:
        """One job as status shows it (``not_found`` when not kept)."""
        job = self.table.get(job_id)
        if job is None:
            raise ProtocolError("not_found", f"no program {job_id} (ids start at 1; finished "
                                             f"programs are kept for the last {HISTORY})")
        return self.running(job) if job is self.current else job.as_dict()

    def wait(self, job_id, timeout: float) -> Wait:
        """A ``wait`` for a job kept (``not_found`` otherwise), ``timeout`` s at most."""
        if job_id not in self.table:
            raise ProtocolError("not_found", f"no program {job_id} (ids start at 1; finished programs "
                                             f"are kept for the last {HISTORY})")
        return Wait(job_id, time.monotonic() + timeout)

    def add_waiter(self, wait: Wait, identity, request_id, version) -> None:
        """A wait to answer when its program ends (or at its deadline)."""
        self.waiters.append((wait, identity, request_id, version))
        self.answer_waiters()

    def answer_waiters(self, now: float | None = None) -> None:
        """Answer every ``wait`` whose program has ended, or whose deadline has passed."""
        if not self.waiters:
            return
        now = time.monotonic() if now is None else now
        keep = []
        for entry in self.waiters:
            wait, identity, request_id, version = entry
            job = self.table.get(wait.program)
            ended = job is None or job.state.ended
            if not ended and now < wait.deadline:
                keep.append(entry)
                continue
            if job is None:
                reply = protocol.error(request_id, "not_found", f"no program {wait.program} (finished programs are "
                                                                f"kept for the last {HISTORY})", version)
            else:
                result = self.running(job) if job is self.current else job.as_dict()
                if not ended:
                    result["timed_out"] = True
                reply = protocol.ok(request_id, result, version)
            self.reply(identity, reply)
        self.waiters = keep
