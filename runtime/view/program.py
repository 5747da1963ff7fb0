"""``irl view PROG.irl``: the paths a program's moves will take, before the robot moves.

The paths come from ``irl check``'s run of the program (:func:`runtime.loop.offline.check_motion`
with ``trace``): the runtime's own planners, blends included, the setpoint every 5 ms, so a
path drawn is the path the robot will follow. Each move is drawn as its tool centre
point's path in the colour of its kind, with a marker at its end; picking a marker (or a
move in the list) names the move with its source line, shows it in the source, and puts
the arm at its end. A move the robot would refuse is drawn red (the PTP move ``irl check``
stands in with, to its target) and listed with ``irl check``'s reason. A time slider plays
the program's motion.
"""
from __future__ import annotations

import html
from bisect import bisect_right

from runtime.loop.offline import Outcome
from runtime.motion.moves import Frames
from runtime.view.stage import Player, Stage, source_html

#: The colours of the moves (RGB), by kind; a refused move's stand-in in red.
KIND_COLOURS = {"ptp": (40, 110, 200), "lin": (30, 150, 60), "circ": (140, 60, 170)}
REFUSED_COLOUR = (220, 30, 30)
SELECTED_COLOUR = (255, 200, 0)
#: Up to this many moves, each target is labelled with its line (a checkbox turns them on).
LABELLED_MOVES = 60


class ProgramView:
    """The program's paths on ``stage`` (its source ``text``, the check's ``outcome``
    with its trace)."""

    def __init__(self, stage: Stage, name: str, text: str, outcome: Outcome):
        self.stage, self.outcome, self.name = stage, outcome, name
        self.lines = text.splitlines()
        trace = outcome.trace
        self.records = trace.records
        self.refused = trace.stand_in
        self.times = trace.times
        self.joints = trace.joints
        self.move_of = trace.move
        default = Frames.default(stage.spec)
        frames = [default] + [r.frames or default for r in self.records]
        self.frames = [frames[k] for k in self.move_of]
        self.points = stage.tcp_points(self.joints, self.frames)
        self.selected: int | None = None
        self.reasons = self._reasons()
        self.marked: list[int] = []  # the moves with a marker, in the markers' order
        self.labels: list = []  # per move, its label (None: not made)
        self._draw()
        self._panel()
        self.show_time(self.times[0] if self.times else 0.0)

    def _reasons(self) -> dict[int, str]:
        """Each refused move's line -> what ``irl check`` says of it."""
        reasons: dict[int, str] = {}
        for f in self.outcome.findings:
            if f.kind == "move" and not f.file:
                reasons.setdefault(f.line, f.message + (f" (hint: {f.hint})" if f.hint else ""))
        return reasons

    def _samples(self, k: int) -> range:
        """The trace's samples of move ``k`` (from 1), the last of the move before included."""
        first = next((i for i, m in enumerate(self.move_of) if m == k), None)
        if first is None:
            return range(0)
        last = first
        while last + 1 < len(self.move_of) and self.move_of[last + 1] == k:
            last += 1
        return range(max(first - 1, 0), last + 1)

    def _draw(self) -> None:
        """Every move's path as one set of line segments, every target as one batch of
        markers (a software renderer draws hundreds of moves this way: one object each)."""
        import numpy as np
        import trimesh

        scene = self.stage.server.scene
        self.spans = [self._samples(k) for k in range(1, len(self.records) + 1)]
        self.labels = [None] * len(self.records)
        segments, colours, ends, self.marked = [], [], [], []
        for k, samples in enumerate(self.spans, start=1):
            if len(samples) < 2 or not self.points:
                continue
            colour = self._colour(k)
            pts = _thinned([self.points[i] for i in samples])
            segments += zip(pts, pts[1:])
            colours += [(colour, colour)] * (len(pts) - 1)
            ends.append(pts[-1])
            self.marked.append(k)
        if not segments:
            return
        scene.add_line_segments("/paths", points=np.array(segments), colors=np.array(colours, dtype=np.uint8),
                                line_width=2.5)
        ball = trimesh.creation.icosphere(subdivisions=1, radius=0.008)
        markers = scene.add_batched_meshes_simple(
            "/targets", ball.vertices, ball.faces, batched_wxyzs=np.tile((1.0, 0.0, 0.0, 0.0), (len(ends), 1)),
            batched_positions=np.array(ends), batched_colors=np.array([self._colour(k) for k in self.marked],
                                                                      dtype=np.uint8), cast_shadow=False)
        markers.on_click(lambda event: self._picked(event.instance_index))
        many = len(self.records) > LABELLED_MOVES
        for i, k in enumerate(self.marked):
            if not many or k in self.refused:  # (a label is a page element: made only when shown)
                self._label(k, ends[i])

    def _colour(self, k: int) -> tuple:
        return REFUSED_COLOUR if k in self.refused else KIND_COLOURS.get(self.records[k - 1].kind, (90, 90, 90))

    def _picked(self, instance: int | None) -> None:
        if instance is not None and 0 <= instance < len(self.marked):
            self.select(self.marked[instance])

    def _label(self, k: int, position) -> None:
        """Label move ``k``'s target with its line."""
        text = f"{'refused: ' if k in self.refused else ''}line {self.records[k - 1].line}"
        self.labels[k - 1] = self.stage.server.scene.add_label(f"/labels/move_{k}", text, font_screen_scale=0.7,
                                                               position=position)

    def _panel(self) -> None:
        gui = self.stage.server.gui
        outcome = self.outcome
        refused = sorted(self.reasons.items())
        cycle = f"{outcome.cycle_time:.3f} s" if outcome.cycle_time is not None else "not known (the run did not end)"
        gui.add_markdown(f"**{html.escape(self.name)}** on {html.escape(self.stage.spec.name)}: "
                         f"{len(self.records)} moves, cycle time {cycle}, "
                         f"{len(refused)} refused")
        if refused:
            gui.add_html('<div class="irl-refused" style="font-size:12px; color:#c62828">' + "".join(
                f'<div data-line="{line}">line {line}: {html.escape(reason)}</div>' for line, reason in refused)
                + "</div>")
        options = ["(none)"] + [self._option(k) for k in range(1, len(self.records) + 1)]
        self.choice = gui.add_dropdown("move", options, initial_value="(none)")
        self.choice.on_update(lambda _event: self._chosen())
        self.info = gui.add_markdown("Pick a move's marker in the scene, or a move above.")
        self.label_box = gui.add_checkbox("line numbers at every target", len(self.records) <= LABELLED_MOVES)
        self.label_box.on_update(lambda _event: self._labels())
        self.source = gui.add_html(source_html(self.lines, None, self.name))
        start = self.times[0] if self.times else 0.0
        self.player = Player(gui, start, self.times[-1] if self.times else 0.0, self.show_time)

    def _option(self, k: int) -> str:
        record = self.records[k - 1]
        return f"{k}: line {record.line}, {record.kind}" + (" (refused)" if k in self.refused else "")

    def _chosen(self) -> None:
        value = self.choice.value
        if value != "(none)":
            self.select(int(value.split(":")[0]), from_list=True)

    def _labels(self) -> None:
        on = self.label_box.value
        for k, label in enumerate(self.labels, start=1):
            if label is None and on and k in self.marked:
                self._label(k, self.points[self.spans[k - 1][-1]])
            elif label is not None:
                label.visible = on or k in self.refused

    def select(self, k: int, from_list: bool = False) -> None:
        """Name move ``k`` (from 1), mark its path and line, and put the arm at its end."""
        record = self.records[k - 1]
        self.selected = k
        samples = self.spans[k - 1]
        scene = self.stage.server.scene
        if len(samples) >= 2 and self.points:
            pts = [self.points[i] for i in samples]
            scene.add_line_segments("/paths/selected", points=[(a, b) for a, b in zip(pts, pts[1:])],
                                    colors=SELECTED_COLOUR, line_width=5.0)
        if not from_list:
            self.choice.value = self._option(k)
        duration = f"{record.planned_duration:.3f} s planned" if record.planned_duration is not None else ""
        text = (f"**move {k}**, line {record.line}: `move {record.kind}`, {duration}"
                f"{', blended into the next' if record.blended else ''}")
        if k in self.refused:
            text += f"\n\n**refused**: {self.reasons.get(record.line, 'see irl check')}"
        self.info.content = text
        self.source.content = source_html(self.lines, record.line, self.name,
                                          {line: "#ffcdd2" for line in self.reasons})
        if samples:
            self.stage.show(self.joints[samples[-1]], self.frames[samples[-1]])

    def show_time(self, t: float) -> None:
        """The arm where the program has it at ``t`` (s after its start)."""
        if not self.times:
            return
        i = max(bisect_right(self.times, t) - 1, 0)
        self.stage.show(self.joints[i], self.frames[i])
        k = self.move_of[i]
        if k and k != self.selected:
            self.selected = k
            record = self.records[k - 1]
            self.info.content = f"**move {k}**, line {record.line}: `move {record.kind}` (at {t:.2f} s)"
            self.source.content = source_html(self.lines, record.line, self.name,
                                              {line: "#ffcdd2" for line in self.reasons})

    def close(self) -> None:
        self.player.close()


#: The most a drawn path departs from the planned one (m): the drawing keeps a sample only
#: where leaving it out would move the path further (a software renderer draws a program of
#: hundreds of moves from a few thousand segments instead of tens of thousands).
DRAWN_TOLERANCE = 0.5 / 1000


def _thinned(points: list) -> list:
    """``points`` (a path) without the ones within :data:`DRAWN_TOLERANCE` of the path drawn
    through the others (Ramer-Douglas-Peucker); the first and the last kept."""
    import numpy as np

    if len(points) <= 2:
        return points
    p = np.asarray(points, dtype=float)
    keep = np.zeros(len(p), dtype=bool)
    keep[0] = keep[-1] = True
    stack = [(0, len(p) - 1)]
    while stack:
        a, b = stack.pop()
        if b - a < 2:
            continue
        ab = p[b] - p[a]
        ap = p[a + 1:b] - p[a]
        length2 = float(ab @ ab)
        t = np.clip(ap @ ab / length2, 0.0, 1.0) if length2 > 0.0 else np.zeros(len(ap))
        d2 = ((ap - t[:, None] * ab) ** 2).sum(axis=1)
        worst = int(d2.argmax())
        if d2[worst] > DRAWN_TOLERANCE ** 2:
            m = a + 1 + worst
            keep[m] = True
            stack += [(a, m), (m, b)]
    return [points[i] for i in np.flatnonzero(keep)]
