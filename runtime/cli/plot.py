"""``irl plot``: one panel per moving axis, position over time, the FSM's phases shaded
and labelled, as the paper's Figure 6 shows; the homing steps (the sub-states of
Initialization Sequence the report's ``state`` column names: Find Sensors, Find Index, Go
To Start) as a thin band along the top of the first panel, each named; when the report has
the ``move`` columns (``report.columns``, or ``irl run --report-columns +move``), a thin
vertical line on every panel where each of the program's moves starts, labelled with its
source line (``L12``) on the first panel. The labels (phases, homing steps, moves) are
stacked in rows so that none overlaps another. From the events file beside the report
(``<report>.events.csv``: runtime.recording.EVENTS), a line across every panel where the
cycle faulted (red, labelled FAULT, the fault's text in red under the title) and where an
interrupt fired (orange, dashed, labelled with the interrupt's name), the labels at the
top of the first panel. An axis is drawn when it moved or was commanded to (the reference
moved): an axis whose drive did nothing is there. When the report has the tool centre point
(the ``tcp`` columns), a path view beside them: the TCP during Move Robot seen from above
(x-y) and from the side (x-z), so Cartesian programs show their lines and arcs; when it
has the ``io`` columns, a lane per digital input (green) and output (red) that is ever on.
Needs matplotlib (the ``plot`` extra)."""
from __future__ import annotations

import csv
from pathlib import Path

from runtime.recording import read_events


HOMING = "Initialization Sequence"  # the phase whose sub-states are the homing steps
STEP_BAND = ("#b8c4d6", "#8a9bb5")  # the homing steps' band, alternating
STEP_COLOR = "#4a5a78"  # the homing steps' labels
MOVE_COLOR = "#7b1fa2"  # the moves' start lines and labels
MARK_ROWS = 4  # rows of homing-step and move labels at most
#: The events marked on every panel (runtime.recording.EVENTS kinds): colour and line style.
MARKED = {"fault": ("#c62828", "-"), "interrupt": ("#ef6c00", "--")}


class PlotError(Exception):
    pass


def read_report(path: str | Path):
    """(times, states, {column: values}) from a report CSV (NumPy arrays)."""
    import numpy as np

    from runtime.loop.components.report import is_text  # (the frame group's names: not plotted)

    try:
        with open(path, newline="", encoding="utf-8") as f:
            rows = list(csv.reader(f))
    except OSError as exc:
        raise PlotError(f"cannot read {path}: {exc.strerror or exc}") from None
    if len(rows) < 2 or rows[0][:2] != ["time", "state"]:
        raise PlotError(f"{path} is not an irl report (expected a header starting with time,state)")
    header, body = rows[0], rows[1:]
    try:
        times = np.array([float(r[0]) for r in body])
        columns = {name: np.array([float(r[i]) for r in body]) for i, name in enumerate(header)
                   if i >= 2 and not is_text(name)}
    except (ValueError, IndexError):
        raise PlotError(f"{path}: malformed row (not a complete irl report)") from None
    return times, [r[1] for r in body], columns


def phases(times, states, transitions=()):
    """[(start, end, name)] of the top-level states: from the states file's transitions
    ``(time, from, to)`` when given (every phase, Start Robot too, which ends before the
    report's first row), else from consecutive rows in the same state."""
    if transitions:
        out = []
        end = float(times[-1]) if len(times) else 0.0
        for t, _source, target in transitions:
            top = target.split("/")[0]
            if out and out[-1][2] == top:
                continue
            if out:
                out[-1][1] = t
            out.append([t, end, top])
        return [tuple(p) for p in out]
    out = []
    for t, s in zip(times, states):
        top = s.split("/")[0]
        if out and out[-1][2] == top:
            out[-1][1] = t
        else:
            out.append([t, t, top])
    return [tuple(p) for p in out]


def homing_steps(times, states, parent: str = HOMING) -> list[tuple[float, float, str]]:
    """[(start, end, step)] of the sub-states of ``parent`` (the homing steps), from the
    report's ``state`` column (``Initialization Sequence/Find Index``; the states file
    lists the top-level transitions only): a step runs from its first row to the first
    row in another state (or the report's last row)."""
    out: list[list] = []
    prefix = parent + "/"
    for t, s in zip(times, states):
        step = s[len(prefix):] if s.startswith(prefix) else None
        if out and out[-1][1] is None:  # a step is open
            if step == out[-1][2]:
                continue
            out[-1][1] = float(t)
        if step:
            out.append([float(t), None, step])
    if out and out[-1][1] is None:
        out[-1][1] = float(times[-1])
    return [tuple(step) for step in out]


def move_starts(times, cols) -> list[tuple[float, int, int]]:
    """[(time, move, line)]: the first row of each of the program's moves, from the report's
    ``move`` columns (none without them): where ``move`` goes up, and the move's source line
    (``line``; 0 if the move ended before the row)."""
    if "move" not in cols or "line" not in cols:
        return []
    out = []
    last = 0
    for t, number, line in zip(times, cols["move"], cols["line"]):
        if number > last:
            out.append((float(t), int(number), int(line)))
            last = number
    return out


def read_transitions(report: str | Path) -> list[tuple[float, str, str]]:
    """The report's states file (``<report>.states.csv``), if it is there and readable."""
    path = Path(report).with_suffix(".states.csv")
    try:
        with open(path, newline="", encoding="utf-8") as f:
            rows = list(csv.reader(f))[1:]
        return [(float(r[0]), r[1], r[2]) for r in rows if len(r) == 3]
    except (OSError, ValueError):
        return []


def event_marks(events) -> list[tuple[float, str, str]]:
    """[(time, kind, label)] of the events a plot marks (:data:`MARKED`): the fault,
    labelled FAULT, and each interrupt firing, labelled with its text up to "fired" (the
    interrupt's name)."""
    out = []
    for t, kind, line, text in events:
        if kind in MARKED:
            label = "FAULT" if kind == "fault" else text.split(" fired", 1)[0]
            out.append((t, kind, f"{label} (L{line})" if line else label))
    return out


def _mark_events(panels, marks, first, end: float) -> None:
    """A line across every panel at each marked event; the labels at the top of the
    first panel, beside their lines (left of those in the last third), in rows that do not
    overlap."""
    for ax in panels:
        for k, (t, kind, _label) in enumerate(marks):
            color, style = MARKED[kind]
            new = kind not in [m[1] for m in marks[:k]]
            ax.axvline(t, color=color, ls=style, lw=1.4, zorder=3,
                       label=("fault" if kind == "fault" else "interrupt fired") if ax is first and new else None)
    # a label about len/130 of the axis wide (label_rows' measure), beside its line
    sides = ["right" if end and t > 2 * end / 3 else "left" for t, _kind, _label in marks]
    spans = [(t + (-1 if side == "right" else 1) * len(label) / 260 * end,) * 2 + (label,)
             for (t, _kind, label), side in zip(marks, sides)]
    for (t, kind, label), side, row in zip(marks, sides, label_rows(spans, end)):
        first.text(t, 0.90 - 0.13 * row, f" {label} ",
                   transform=first.get_xaxis_transform(), ha=side, va="top", fontsize=7,
                   color=MARKED[kind][0], zorder=4, bbox={"facecolor": "white", "edgecolor": "none", "alpha": 0.8,
                                                          "pad": 0.5})


def label_rows(spans, total: float, chars_per_axis: float = 130.0) -> list[int]:
    """A row (0, 1, 2...) for each phase label so that no two labels overlap: a label
    about ``len(name)`` characters wide, of ``chars_per_axis`` across the axis."""
    rows: list[int] = []
    ends: list[float] = []  # per row: where its last label ends (axis fraction)
    for t0, t1, name in spans:
        centre = ((t0 + t1) / 2) / total if total > 0 else 0.0
        half = len(name) / chars_per_axis / 2
        for row, end in enumerate(ends):
            if centre - half > end:
                ends[row] = centre + half
                rows.append(row)
                break
        else:
            ends.append(centre + half)
            rows.append(len(ends) - 1)
    return rows


def io_lanes(cols) -> list[str]:
    """The digital inputs and outputs of a report (its io columns) that are ever on, inputs
    first."""
    from runtime.loop.components.report import is_io

    return [name for name in cols if is_io(name) and cols[name].max() > 0]


def analog_lines(cols) -> list[str]:
    """The analog inputs and outputs of a report (its analog columns) that hold a value."""
    import numpy as np

    return [name for name in cols if name.partition("_")[0] in ("ain", "aout") and name.partition("_")[2].isdigit()
            and np.isfinite(cols[name]).any()]


def _analog_panel(ax, times, cols, lines: list[str]) -> None:
    """One line per analog input (solid) or output (dashed), in its unit (the specification's)."""
    for name in lines:
        ax.plot(times, cols[name], lw=1.2, ls="-" if name.startswith("ain_") else "--",
                label=name.replace("_", "[") + "]")
    ax.set_ylabel("analog")
    ax.legend(loc="upper right", fontsize=7)
    ax.grid(alpha=0.3)


def _io_panel(ax, times, cols, lanes: list[str]) -> None:
    """One step lane per input or output, high while it is on."""
    for k, name in enumerate(lanes):
        color = "#2e7d32" if name.startswith("in_") else "#c62828"
        ax.fill_between(times, k, k + 0.7 * cols[name], step="post", color=color, alpha=0.55, lw=0)
    ax.set_yticks([k + 0.35 for k in range(len(lanes))])
    ax.set_yticklabels([name.replace("_", "[") + "]" for name in lanes], fontsize=7)
    ax.set_ylim(-0.2, len(lanes))
    ax.set_ylabel("I/O")
    ax.grid(alpha=0.3, axis="x")


def _tcp_views(fig, grid, rows: int, times, states, cols) -> None:
    """The TCP path during Move Robot: from above and from the side (mm, equal scales)."""
    import numpy as np

    moving = np.array([s.split("/")[0] == "Move Robot" for s in states])
    if not moving.any():
        moving = np.ones(len(times), dtype=bool)
    x, y, z = (cols[f"tcp_{c}"][moving] for c in ("x", "y", "z"))
    half = max(rows // 2, 1)
    for k, (v, name) in enumerate(((y, "y"), (z, "z"))):
        ax = fig.add_subplot(grid[k * half:(k + 1) * half if k == 0 else rows, 2])
        ax.plot(x, v, lw=1.0, color="#1f4e99")
        ax.plot(x[:1], v[:1], "o", ms=4, color="#2e7d32", label="start")
        ax.plot(x[-1:], v[-1:], "s", ms=4, color="#c62828", label="end")
        ax.set_xlabel("x (mm)")
        ax.set_ylabel(f"{name} (mm)")
        ax.set_aspect("equal", adjustable="datalim")
        ax.grid(alpha=0.3)
        ax.set_title("TCP from above" if name == "y" else "TCP from the side", fontsize=9)
        if k == 0:
            ax.legend(loc="best", fontsize=7)


def plot_report(report: str | Path, output: str | Path) -> None:
    """Draw ``report`` into ``output`` (PNG, PDF or SVG: by its suffix)."""
    fig = figure(report)
    import matplotlib.pyplot as plt

    try:
        Path(output).parent.mkdir(parents=True, exist_ok=True)
        fig.savefig(output, dpi=110)
    except OSError as exc:
        raise PlotError(f"cannot write {output}: {exc.strerror or exc}") from None
    finally:
        plt.close(fig)


def figure(report: str | Path):
    """The matplotlib figure of ``report`` (the caller closes it)."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        raise PlotError("matplotlib is not installed: pip install 'irl[plot]'") from None
    import numpy as np

    times, states, cols = read_report(report)
    axes_names = [c[len("sens_pos_"):] for c in cols if c.startswith("sens_pos_")]
    moving = [a for a in axes_names if any(np.ptp(cols[f"{kind}_{a}"]) > 1e-6 for kind in ("sens_pos", "desi_pos")
                                           if f"{kind}_{a}" in cols)] or axes_names[:1]
    has_tcp = all(f"tcp_{c}" in cols for c in ("x", "y", "z"))
    lanes = io_lanes(cols)
    analog = analog_lines(cols)
    extra = (1 if lanes else 0) + (1 if analog else 0)
    rows = max(len(moving) + extra, 2 if has_tcp else 1)
    fig = plt.figure(figsize=(15 if has_tcp else 10, 1.9 * rows + 1))
    grid = fig.add_gridspec(rows, 3 if has_tcp else 1)
    first = fig.add_subplot(grid[0, :2] if has_tcp else grid[0, 0])
    panels = np.array([[first]] + [[fig.add_subplot(grid[i, :2] if has_tcp else grid[i, 0], sharex=first)]
                                   for i in range(1, len(moving) + extra)])
    if has_tcp:
        _tcp_views(fig, grid, rows, times, states, cols)
    colors = ["#dde8f5", "#f5e6d3", "#e1f0dc", "#f3dbe7", "#ececec"]
    spans = phases(times, states, read_transitions(report))
    steps = homing_steps(times, states)
    starts = move_starts(times, cols)
    for ax in panels[:, 0]:
        for k, (t0, t1, phase) in enumerate(spans):
            ax.axvspan(t0, t1, color=colors[k % len(colors)], lw=0)
        for k, (t, _number, _line) in enumerate(starts):
            ax.axvline(t, color=MOVE_COLOR, lw=0.7, ls=":", zorder=1,
                       label="move start (its line)" if k == 0 and ax is first else None)
    if lanes:
        _io_panel(panels[len(moving), 0], times, cols, lanes)
    if analog:
        _analog_panel(panels[-1, 0], times, cols, analog)
    events = read_events(report)
    for ax, name in zip(panels[:, 0], moving):
        ax.plot(times, cols[f"sens_pos_{name}"], lw=2.2, color="#1f4e99", alpha=0.55, label="encoder")
        ax.plot(times, cols[f"desi_pos_{name}"], lw=0.9, ls="--", color="#d35400", label="reference")
        ax.set_ylabel(f"{name} (deg)")
        ax.grid(alpha=0.3)
    top = panels[0, 0]
    end = max(float(times[-1]) if len(times) else 0.0, spans[-1][1] if spans else 0.0)
    top.set_xlim(0.0, end)
    _mark_events(panels[:, 0], event_marks(events), first, end)
    for k, (t0, t1, _step) in enumerate(steps):  # the homing steps: a thin band along the top
        top.axvspan(t0, t1, ymin=0.94, ymax=1.0, color=STEP_BAND[k % len(STEP_BAND)], lw=0)
    # just above the first panel: the homing steps' and the moves' labels, then the phases'
    marks = sorted([(t0, t1, step, STEP_COLOR) for t0, t1, step in steps]
                   + [(t, t, f"L{line}" if line else f"#{number}", MOVE_COLOR) for t, number, line in starts],
                   key=lambda mark: mark[0] + mark[1])
    # (many short moves: the labels beyond MARK_ROWS rows are left out, not their lines)
    shown = [(mark, row) for mark, row in zip(marks, label_rows([m[:3] for m in marks], end)) if row < MARK_ROWS]
    for (t0, t1, text, color), row in shown:
        top.text((t0 + t1) / 2, 1.01 + 0.11 * row, text, transform=top.get_xaxis_transform(), ha="center",
                 va="bottom", fontsize=7, color=color)
    base = 1.02 + 0.11 * (max(row for _mark, row in shown) + 1) if shown else 1.02
    for (t0, t1, phase), row in zip(spans, label_rows(spans, end)):
        top.text((t0 + t1) / 2, base + 0.14 * row, phase, transform=top.get_xaxis_transform(), ha="center",
                 va="bottom", fontsize=8)
    panels[0, 0].legend(loc="lower right", fontsize=7)
    for ax in panels[:-1, 0]:
        ax.tick_params(labelbottom=False)
    panels[-1, 0].set_xlabel("time (s)")
    fig.suptitle(f"{Path(report).name}: positions read from the encoders, by FSM phase", y=0.995)
    faults = [(t, text) for t, kind, _line, text in events if kind == "fault"]
    for t, text in faults[:1]:  # (a cycle has one fault)
        fig.text(0.5, 0.975, f"FAULT at {t:.3f} s: {text}", ha="center", va="top", fontsize=8.5,
                 color=MARKED["fault"][0], wrap=True)
    fig.tight_layout(rect=(0, 0, 1, 0.965 if faults else 1))
    return fig
