"""A search move at work (``move lin TARGET search := N``: compiler.clauses' ``search``;
RAPID's SearchL): the trajectory generator's watch of digital input N while the move runs.

The program hands the move over with the robot at rest (``SEARCH_BEGIN``, a barrier). The
search is *armed* then; an input already true ends it at once, found nothing, and the
robot does not move. Every 5 ms update after the setpoint (:meth:`Search.watch`): where the
input is true, the robot is *found* there (its measured joints at that update, the
setpoint's in an offline run, and the move's tool and base) and the motion is cut (:meth:`MotionQueue.cut
<runtime.motion.motionqueue.MotionQueue.cut>`: a stop on the path, the rest dropped); where
the move has ended without it, the search found nothing. ``SEARCH_END`` (a barrier: once
the robot is at rest) then reads :meth:`Search.end`: nothing, or the program's search
error (compiler.recovery). ``search_pose()`` reads :attr:`Search.found`.

How far it is from where the input changed: the watch sees the input at each 5 ms update,
so the pose (the measured joints then) is at most one update's travel past it (0.5 mm at
100 mm/s), plus the sensor's delay: search slowly. The robot then stops on its path, at the
move's acceleration, beyond that pose.

Real-time: :meth:`watch` reads a port value and compares; nothing else happens in a tick.
"""
from __future__ import annotations

__all__ = ["Search"]


class Search:
    """The search move under way (``input``: the digital input watched; None: no search
    is), how the last one ended (``outcome``: why it found nothing, None: it found its
    input), and where the last one that found its input did (``found``: the joints and the
    move's frames, None before any)."""

    def __init__(self):
        self.reset()

    def reset(self) -> None:
        """A new program: no search under way, none found."""
        self.input: int | None = None
        self.line = 0
        self.frames = None
        self.outcome: str | None = None
        self.found: tuple | None = None
        self._setpoints = True
        #: an offline run in the assumed cell (runtime.loop.offline): the input becomes true
        #: where the move ends (for this search only)
        self.found_at_end = False

    @property
    def armed(self) -> bool:
        return self.input is not None

    def arm(self, n: int, line: int, frames, motion, already: bool) -> bool:
        """A search move of ``line`` watching input ``n`` is handed over, with the move's
        ``frames``; ``already``: the input is true now. Whether the move is to be made
        (False: the search ended at once, found nothing). While it runs, the motion queue
        computes every setpoint (an offline run skips them)."""
        self.outcome = None
        if already:
            self.input = None
            self.outcome = f"in[{n}] was true already when the search began: a search stops where its input becomes true"
            return False
        self.input, self.line, self.frames = n, line, frames
        self._setpoints, motion.setpoints = motion.setpoints, True
        return True

    def watch(self, inputs: tuple, motion, measured: tuple | None = None) -> float | None:
        """Real-time, after each update's setpoint: the input true (found where the robot
        is, ``measured``: its measured joints, else the setpoint's; the motion is cut;
        returns the time within which the robot will be at rest), or the move ended
        without it (found nothing). None otherwise."""
        n = self.input
        if n is None:
            return None
        if 0 < n <= len(inputs) and inputs[n - 1]:
            self.found = (tuple(measured or motion.positions), self.frames)
            self._disarm(motion)
            return motion.cut()
        if motion.done(triggers=False):
            if self.found_at_end:
                self.found = (tuple(motion.positions), self.frames)
            else:
                self.outcome = f"the move reached its target and in[{n}] did not become true on the way"
            self._disarm(motion)
        return None

    def cancel(self, motion) -> None:
        """The search move was refused, or the program stopped: no search is under way."""
        if self.input is not None:
            self._disarm(motion)

    def _disarm(self, motion) -> None:
        self.input = None
        self.found_at_end = False
        motion.setpoints = self._setpoints

    def end(self) -> str | None:
        """``SEARCH_END``: why the search move just ended found nothing, or None (found)."""
        if self.input is not None:  # (object code that ends a search before its move has: forged)
            return f"the search at line {self.line} has not ended"
        outcome, self.outcome = self.outcome, None
        return outcome
