"""The stage every view shares: a viser server on 127.0.0.1 and, in its 3D scene, the arm
(drawn from the URDF ``irl urdf`` writes: one description of the arm), the tool centre
point of the active tool and the active base as coordinate frames, the specification's
named frames; in its panel, the program's source with the current line marked, and the
small HTML pieces the views show (lamps, a time line, a log).

Units: the scene is in metres (the URDF's); joint values and poses come in as the rest of
``irl`` has them (deg, mm).
"""
from __future__ import annotations

import html
import io
import threading
from math import radians

from compiler.geometry import rpy_to_quat

from runtime.motion.tcp import tcp_of
from runtime.motion.moves import Frames
from runtime.motion.urdf import urdf_text
from runtime.timing import SETPOINT_PERIOD  # the slider's step: a setpoint of a program's trace

#: The address the page is served on: this machine only (docs/runtime.md says how to reach
#: it from another one).
HOST = "127.0.0.1"
#: The port ``irl view`` tries first (the next free one when it is taken).
DEFAULT_PORT = 8765
#: Lines of source the panel shows around the current line.
SOURCE_WINDOW = 15

MM = 1 / 1000  # the scene's metres per mm
#: How a world zone is drawn (compiler.zones.KINDS): its colour by kind, and how opaque.
ZONE_COLOURS = {"forbidden": (220, 40, 40), "signal": (235, 160, 20)}
ZONE_OPACITY = 0.3


class Stage:
    """A viser server showing ``spec``'s arm: :meth:`show` poses it."""

    def __init__(self, spec, port: int = DEFAULT_PORT, title: str = "irl view"):
        import viser
        import yourdfpy
        from viser.extras import ViserUrdf

        self.spec = spec
        self.server = viser.ViserServer(host=HOST, port=port, verbose=False)
        self.server.gui.configure_theme(control_layout="fixed", control_width="large", show_logo=False,
                                        show_share_button=False, brand_color=(230, 120, 20))
        self.server.scene.set_up_direction("+z")
        # lit by plain lights, not viser's default environment map (image-based lighting): a
        # software renderer (a machine without a GPU, a headless browser) draws the scene at 1
        # frame a second with it, at 50 without; shadows show nothing a programmer needs
        self.server.scene.configure_environment_map(hdri=None)
        self.server.scene.configure_default_lights(enabled=True, cast_shadow=False)
        self.server.scene.add_light_hemisphere("/light/sky", sky_color=(255, 255, 255), ground_color=(120, 120, 130),
                                               intensity=1.2)
        reach = sum(abs(a.dh.a) + abs(a.dh.d) for a in spec.main_axes if a.dh is not None) * MM or 1.0
        self.server.initial_camera.position = (0.95 * reach, -0.95 * reach, 0.7 * reach)
        self.server.initial_camera.look_at = (0.3 * reach, 0.0, 0.3 * reach)
        self.title = title
        self.lock = threading.Lock()  # the views' threads and viser's callbacks pose the arm one at a time
        urdf = yourdfpy.URDF.load(io.StringIO(urdf_text(spec)))
        self.arm = ViserUrdf(self.server, urdf, root_node_name="/arm")
        names = self.arm.get_actuated_joint_names()
        axes = [a.name for a in spec.main_axes]
        self._order = [axes.index(n) for n in names]  # the URDF's actuated joints, as axis indices
        self.tcp = tcp_of(spec)
        self.server.scene.add_grid("/ground", width=2.0, height=2.0, cell_size=0.1, plane="xy")
        for kind, name, values in spec.named_frames:
            if kind == "tool":
                continue
            self.server.scene.add_frame(f"/frames/{name}", axes_length=0.08, axes_radius=0.003,
                                        position=_m(values[:3]), wxyz=rpy_to_quat(*values[3:]))
            self.server.scene.add_label(f"/frames/{name}/label", name, font_screen_scale=0.8)
        self.tool = self.server.scene.add_frame("/tool", axes_length=0.06, axes_radius=0.004)
        self.base = self.server.scene.add_frame("/base", axes_length=0.12, axes_radius=0.004)
        self.base_label = self.server.scene.add_label("/base/label", "world", font_screen_scale=0.8)
        self.zones: dict = {}  # the world zones shown: name -> its shape's handle (compiler.zones)
        self.show_zones(spec.zones)
        self.joints: tuple | None = None  # what the arm shows (deg)
        self.announced = False  # its URL said
        self.show([a.home for a in spec.main_axes])

    @property
    def url(self) -> str:
        return f"http://{HOST}:{self.server.get_port()}/"

    def show(self, joints, frames: Frames | None = None, tcp=None) -> None:
        """Pose the arm at ``joints`` (deg, the main axes first) with the tool centre point
        and base of ``frames`` (None: the specification's tool in the world frame); ``tcp``:
        the tool centre point (x, y, z mm, roll, pitch, yaw deg, world) when it is known."""
        joints = tuple(float(v) for v in joints)
        with self.lock:
            self.joints = joints
            self.arm.update_cfg([radians(joints[i]) for i in self._order])
            if tcp is None and self.tcp is None:
                return
            x, y, z, roll, pitch, yaw = tcp if tcp is not None else self.tcp.world(joints[:6], frames)
            self.tool.position, self.tool.wxyz = _m((x, y, z)), rpy_to_quat(roll, pitch, yaw)
            if frames is not None:
                base = frames.base
                self.base.position, self.base.wxyz = _m(base[:3]), rpy_to_quat(*base[3:])
                if self.base_label.text != frames.base_name:
                    self.base_label.text = frames.base_name

    def show_zones(self, zones) -> None:
        """Draw the world ``zones`` (compiler.zones: the specification's, a program's own):
        translucent, a forbidden zone red, a signal zone amber, each named above it."""
        scene = self.server.scene
        for zone in zones:
            if zone.name in self.zones:
                continue
            node = f"/zones/{len(self.zones)}"
            colour = ZONE_COLOURS[zone.kind]
            (lx, ly, lz), (hx, hy, hz) = zone.low, zone.high
            if zone.shape == "box":
                handle = scene.add_box(node, colour, _m((hx - lx, hy - ly, hz - lz)), opacity=ZONE_OPACITY,
                                       position=_m(((lx + hx) / 2, (ly + hy) / 2, (lz + hz) / 2)), cast_shadow=False)
            else:  # (viser's cylinder stands along its z: the world's up)
                handle = scene.add_cylinder(node, zone.radius * MM, (hz - lz) * MM, colour, opacity=ZONE_OPACITY,
                                            position=_m((zone.centre[0], zone.centre[1], (lz + hz) / 2)),
                                            cast_shadow=False)
            scene.add_label(f"{node}/label", f"{zone.name} ({zone.kind})", font_screen_scale=0.7,
                            position=(0.0, 0.0, (hz - lz) * MM / 2))
            self.zones[zone.name] = handle

    def tcp_points(self, joints_list, frames_list) -> list:
        """The tool centre point (m, world) of each joint values, each with its frames."""
        tcp = self.tcp
        if tcp is None:
            return []
        return [_m(tcp.world(j[:6], f)[:3]) for j, f in zip(joints_list, frames_list)]

    def close(self) -> None:
        self.server.stop()


def _m(mm) -> tuple:
    return tuple(v * MM for v in mm)


# ---- the panel's HTML pieces -------------------------------------------------------------
_PANEL = "font-family: ui-monospace, monospace; font-size: 12px; line-height: 1.45;"


def source_html(lines: list[str], current: int | None, title: str = "", marks: dict | None = None,
                trail=()) -> str:
    """The source around line ``current`` (from 1), that line marked (``id="current-line"``,
    ``data-line``); ``marks``: line -> a colour for other lines (refused moves); ``trail``:
    the last marks shown, oldest first (the current one last), as (their running count,
    line), the lines passed shaded pale and all of them in the box's ``data-trail`` ("count:line ..."): a page
    that is sent only the latest of several quick updates (a transport coalesces them)
    still learns every line passed, in order."""
    marks = marks or {}
    passed = {line for _count, line in trail}
    shown = f' data-trail="{" ".join(f"{count}:{line or 0}" for count, line in trail)}"' if trail else ""
    n = len(lines)
    if n == 0:
        return f'<div class="irl-source"{shown} style="{_PANEL}">(no source)</div>'
    centre = current if current else 1
    first = max(1, min(centre - SOURCE_WINDOW // 2, n - SOURCE_WINDOW + 1))
    rows = []
    for number in range(first, min(n, first + SOURCE_WINDOW - 1) + 1):
        text = html.escape(lines[number - 1].rstrip()) or "&nbsp;"
        style = "white-space: pre; padding: 0 4px;"
        attrs = f'data-line="{number}"'
        if number == current:
            style += " background: #ffd54f; font-weight: bold;"
            attrs += ' id="current-line"'
        elif number in marks:
            style += f" background: {marks[number]};"
        elif number in passed:
            style += " background: #fff5d6;"
        rows.append(f'<div {attrs} style="{style}"><span style="color:#999">{number:4d}</span>  {text}</div>')
    head = f'<div style="color:#555; margin-bottom: 2px;">{html.escape(title)}</div>' if title else ""
    return f'<div class="irl-source"{shown} style="{_PANEL} overflow-x: auto;">{head}{"".join(rows)}</div>'


def lamps_html(inputs, outputs) -> str:
    """The digital inputs and outputs as lamps (lit: green; ``class="lamp on|off"``)."""
    def row(kind: str, values) -> str:
        lamps = "".join(
            f'<span class="lamp {"on" if v else "off"}" title="{kind}[{i + 1}]" style="display:inline-block; '
            f'width:11px; height:11px; border-radius:6px; margin:1px; border:1px solid #777; '
            f'background:{"#2ecc40" if v else "#ddd"}"></span>' for i, v in enumerate(values))
        return f'<div style="{_PANEL}"><span style="display:inline-block; width:28px">{kind}</span>{lamps}</div>'
    return row("in", inputs) + row("out", outputs)


#: The phases' colours on a time line (the FSM's top-level states), by the start of the name.
PHASE_COLOURS = (("Start", "#b0bec5"), ("Calibrate", "#ffcc80"), ("Initialization", "#a5d6a7"),
                 ("Move", "#90caf9"), ("Stop", "#ef9a9a"), ("Robot Reconfiguration", "#ce93d8"))


def phase_colour(name: str) -> str:
    return next((c for prefix, c in PHASE_COLOURS if name.startswith(prefix)), "#e0e0e0")


def timeline_html(phases: list[tuple[float, str]], start: float, end: float, now: float) -> str:
    """The phases (each ``(from time, state path)``: by their top-level state) as coloured
    bands from ``start`` to ``end``, and a marker at ``now``."""
    span = max(end - start, 1e-9)
    tops: list[tuple[float, str]] = []
    for t, name in phases:
        top = name.split("/")[0]
        if not tops or tops[-1][1] != top:
            tops.append((t, top))
    phases = tops
    bands = []
    for i, (t, name) in enumerate(phases):
        t_end = phases[i + 1][0] if i + 1 < len(phases) else end
        width = max(0.0, (min(t_end, end) - max(t, start)) / span * 100.0)
        label = html.escape(name.split("/")[0])
        bands.append(f'<div class="phase" title="{label} from {t:.2f} s" style="display:inline-block; height:18px; '
                     f'width:{width:.3f}%; background:{phase_colour(name)}; overflow:hidden; font-size:10px; '
                     f'white-space:nowrap; vertical-align:top">{label}</div>')
    at = min(max((now - start) / span * 100.0, 0.0), 100.0)
    marker = (f'<div style="position:absolute; left:{at:.3f}%; top:0; width:2px; height:18px; '
              'background:#d32f2f"></div>')
    return (f'<div class="irl-timeline" style="position:relative; width:100%; height:18px; font-family:sans-serif; '
            f'line-height:18px; white-space:nowrap; overflow:hidden">{"".join(bands)}{marker}</div>')


def log_html(entries: list[tuple[float, str, str]], limit: int = 8) -> str:
    """The last ``limit`` entries ``(time, level, text)``: prints, faults (red), notes."""
    colours = {"ERROR": "#c62828", "WARNING": "#ef6c00"}
    rows = [f'<div class="log {level.lower()}" style="color:{colours.get(level, "#222")}">'
            f'{t:8.3f}  {html.escape(text)}</div>' for t, level, text in entries[-limit:]]
    return f'<div class="irl-log" style="{_PANEL}">{"".join(rows) or "(nothing yet)"}</div>'


class Player:
    """A time slider with play and pause and a playback speed: moving the slider, or
    playing, calls ``on_time(t)`` (from viser's thread or the player's own)."""

    RATES = ("0.25x", "0.5x", "1x", "2x", "5x", "10x", "20x")
    FRAME = 1.0 / 30.0  # s between the frames shown while playing

    def __init__(self, gui, start: float, end: float, on_time):
        self.start, self.end, self.on_time = start, max(end, start + SETPOINT_PERIOD), on_time
        self.slider = gui.add_slider("time (s)", min=round(start, 3), max=round(self.end, 3), step=SETPOINT_PERIOD,
                                     initial_value=round(start, 3))
        self.button = gui.add_button("Play", hint="play from the slider's time at the chosen speed")
        self.rate = gui.add_dropdown("speed", self.RATES, initial_value="1x")
        self.playing = threading.Event()
        self._stop = threading.Event()
        self.slider.on_update(lambda _event: self.on_time(self.slider.value))
        self.button.on_click(lambda _event: self.toggle())
        self.thread = threading.Thread(target=self._play, name="view-player", daemon=True)
        self.thread.start()

    def toggle(self) -> None:
        if self.playing.is_set():
            self.playing.clear()
            self.button.label = "Play"
        else:
            if self.slider.value >= self.end - 1e-6:
                self.slider.value = self.start
            self.playing.set()
            self.button.label = "Pause"

    def _play(self) -> None:
        import time

        last = time.monotonic()
        while not self._stop.is_set():
            if not self.playing.wait(0.2):
                last = time.monotonic()
                continue
            time.sleep(self.FRAME)
            now = time.monotonic()
            rate = float(self.rate.value.rstrip("x"))
            t = min(self.slider.value + (now - last) * rate, self.end)
            last = now
            self.slider.value = round(t, 3)
            if t >= self.end:
                self.playing.clear()
                self.button.label = "Play"

    def close(self) -> None:
        self._stop.set()
