"""The pendant in a real browser (Debian's headless Chromium, driven by Playwright: see
tests/browser.py for when these are skipped), against a wall-clock server in T1, as an
operator uses it: holding a jog button moves the robot and releasing it stops it (the
position in ``status``, read by a client of the test's own), homing too moves only while a
jog button is held, the pause button pauses a running program, and the emergency stop of a
page that does not hold control stops the program of another client that does.

One server for the file, of a robot that homes quickly (quick_homing_spec); each test leaves
control free and the robot at rest. (Not marked ``long``: tests so marked are dealt to different
workers, and each would start its own server and browser.)
"""
from __future__ import annotations

import re
import time

import pytest

from tests.browser import LOAD, View, browser  # noqa: F401 (browser: the fixture)
from tests.conftest import TERMINAL, ServerProcess, objcode, soft_deadline_spec

#: How soon after the release the arm must be at rest (docs/protocol.md, jog: within 0.5 s
#: of the last heartbeat; the release stops it at once).
AT_REST_WITHIN = 0.5
#: A change of a measured position (deg) that is motion, not the encoder's last count (1/1820 deg).
STILL = 0.005
#: A program of long, slow moves (in T1 each takes several seconds), with a print.
SLOW = """program slow;
seq
  print("slow starts");
  move ptp joint(mainjoint(30, -20, 20, 0, 40, 0)) speed_ptp := 0.1;
  move ptp joint(mainjoint(-30, 0, 10, 0, 40, 0)) speed_ptp := 0.1;
  move ptp joint(mainjoint(30, -20, 20, 0, 40, 0)) speed_ptp := 0.1;
endseq
endprogram;
"""


def quick_homing_spec(directory):
    """The test servers' Lola 15 (soft deadlines: tests/conftest.py, soft_deadline_spec) with
    its homing sensors 1 deg from home and the simulated arm parked within 0.5 deg of it:
    homing in T1 takes 5 s of the wall clock instead of 13 (the loop's CPU all along)."""
    path = soft_deadline_spec(directory)
    text = path.read_text(encoding="utf-8").replace("park_spread = 3.0", "park_spread = 0.5")
    text, axes = re.subn(r"(encoder_counts = 4096\n)", r"\1sensor_position = -1.0\nsearch_velocity = 20.0\n", text)
    assert axes == 6 and "park_spread = 0.5" in text
    path.write_text(text, encoding="utf-8")
    return path


class Cell:
    """The server (wall clock, T1), ``irl view`` of it with the pendant, and a client of
    the test's own (it reads the robot's status; it is the other client of the estop test)."""

    def __init__(self, base, browser):
        self.browser = browser
        self.programs = programs = base / "programs"
        programs.mkdir()
        (programs / "slow.irl").write_text(SLOW, encoding="utf-8")
        self.server = ServerProcess(base / "server", base / "state", sim_clock=False, spec=quick_homing_spec(base),
                                    extra=("--mode", "t1")).start()
        self.client = self.server.client()
        self.pages: list = []  # the test's pages (closed after it)
        self.view = View("--endpoint", self.server.endpoint, "--telemetry", self.server.telemetry,
                         "--programs", programs)

    def open(self):
        """The pendant's page (without the 3D view: the tests do not look at it)."""
        page = self.browser.new_page(viewport={"width": 1280, "height": 900})
        self.pages.append(page)
        page.goto(self.view.pendant + "?view=off")
        page.wait_for_selector("#control-pill:not(:text-is('control: ?'))", timeout=LOAD * 1000)
        return page

    def status(self) -> dict:
        return self.client.request("status")

    def wait(self, predicate, what: str, timeout: float = LOAD, abandon=None) -> dict | None:
        """The status once ``predicate(status)``; None as soon as ``abandon()`` (if given)."""
        deadline = time.monotonic() + timeout
        while abandon is None or not abandon():
            status = self.status()
            if predicate(status):
                return status
            if time.monotonic() > deadline:
                pytest.fail(f"not {what} after {timeout} s: {status}\n{self.server.log()}")
            time.sleep(0.05)
        return None

    def tidy(self) -> None:
        """After a test, passed or failed: its pages closed (a closed page gives control back
        and releases its jog), and the next test starts with control free and nothing running."""
        for page in self.pages:
            if not page.is_closed():
                page.close(run_before_unload=True)
        self.pages.clear()
        status = self.wait(lambda s: s["control"] is None or s["running"] is None, "control free or idle")
        if status["running"] is not None:
            self.client.request("estop")
        self.wait(lambda s: s["control"] is None and s["running"] is None, "control free and idle")

    def close(self) -> None:
        code = self.view.stop()
        self.server.stop()
        assert code == 0, "".join(self.view.output)


@pytest.fixture(scope="module")
def pendant_cell(tmp_path_factory, browser):
    cell = Cell(tmp_path_factory.mktemp("pendant"), browser)
    yield cell
    cell.close()


@pytest.fixture
def cell(pendant_cell):
    yield pendant_cell
    pendant_cell.tidy()


def _take(page, name: str = "operator") -> None:
    """Take control from the page. On a loaded host a click can come before the page has
    caught up (the pill still 'free' after a while): click again, at most 3 times, and
    fail with what the page says."""
    from playwright.sync_api import TimeoutError as PageTimeout

    page.fill("#name", name)
    for _ in range(3):
        page.click("#take")
        try:
            page.wait_for_selector("#control-pill.you", timeout=LOAD * 1000 / 3)
            return
        except PageTimeout:
            continue
    pytest.fail(f"the page did not get control: {page.inner_text('body')[:2000]}")


def _give_back(page) -> None:
    page.click("#release")
    page.wait_for_selector("#control-pill:not(.you)", timeout=LOAD * 1000)


def _centre(page, selector: str) -> tuple[float, float]:
    box = page.locator(selector).bounding_box()
    return box["x"] + box["width"] / 2, box["y"] + box["height"] / 2


def _idle(cell) -> None:
    """Until the jog session (or program) has ended: the robot at rest, nothing running."""
    cell.wait(lambda s: s["running"] is None, "idle")


def _still_after(samples: list, t: float) -> float:
    """How long after ``t`` the position (samples: (time, position)) last moved by more
    than STILL from where it ended."""
    end = samples[-1][1]
    moving = [at for at, q in samples if at >= t and max(abs(a - b) for a, b in zip(q, end)) > STILL]
    return (moving[-1] - t) if moving else 0.0


def _stalls(cell, page) -> int:
    """How many jogs so far the deadman stopped: the pendant for a page's heartbeats that
    stopped coming (its note), or the server for the pendant's (the session's reason). A
    loaded host that stalls Chromium or irl view for over 0.25 s does that, as it must."""
    notes = sum("no heartbeat" in n["text"] for n in page.evaluate("window.__pendant.notes"))
    reason = (cell.status()["jog"] or {}).get("reason") or ""
    return notes + ("no heartbeat" in reason)


def _press_until(cell, page, selector: str, predicate, what: str, tries: int = 4) -> dict:
    """Press the button and hold it until ``predicate(status)``; pressed again (a new
    press: a jog never starts again by itself) when the deadman stopped it on a stalled
    host, at most ``tries`` times. The button is left held."""
    for _ in range(tries):
        stalls = _stalls(cell, page)
        page.mouse.move(*_centre(page, selector))
        page.mouse.down()
        status = cell.wait(predicate, what, abandon=lambda: _stalls(cell, page) != stalls)
        if status is not None:
            return status
        page.mouse.up()
    pytest.fail(f"not {what}: the deadman stopped each of {tries} presses (lost heartbeats)\n{cell.server.log()}")


def _hold(cell, page, selector: str, seconds: float, then=None) -> tuple[list, float]:
    """Press the button, hold it ``seconds`` (``then(page)`` ends the hold: default, the
    pointer comes up), watching the position (epoch s); (the samples, the time of the
    page's release: its pointer event's, or its blur's)."""
    page.mouse.move(*_centre(page, selector))
    samples = []
    start = time.time()
    page.mouse.down()
    while time.time() - start < seconds:
        samples.append((time.time(), cell.status()["position"]))
        time.sleep(0.03)
    releases = page.evaluate("window.__pendant.releases.length")
    (then or (lambda p: p.mouse.up()))(page)
    page.wait_for_function(f"window.__pendant.releases.length > {releases}", timeout=LOAD * 1000)
    released = page.evaluate("window.__pendant.releases.at(-1).at") / 1000.0
    while time.time() - released < AT_REST_WITHIN + 0.7:
        samples.append((time.time(), cell.status()["position"]))
        time.sleep(0.03)
    page.mouse.up()
    return samples, released


A1_PLUS = 'button.jog[data-axis="A1"][data-dir="1"]'
A1_MINUS = 'button.jog[data-axis="A1"][data-dir="-1"]'


def test_homing_moves_only_while_a_jog_button_is_held(cell):
    """The robot is not homed: a jog button held starts the jog session, which homes first;
    released before homing has ended, the session is aborted (the arm comes to rest)."""
    assert not cell.status()["initialized"]
    page = cell.open()
    # (the 3D view it embeds comes from another site, localhost: the browser gives it a process
    # of its own, and its software-rendered WebGL cannot hold up this page's heartbeats)
    assert page.evaluate("window.__pendant.cfg.view") == cell.view.url.replace("127.0.0.1", "localhost")
    _take(page)
    page.wait_for_selector("#jog-note:text('not homed')", timeout=LOAD * 1000)
    _press_until(cell, page, A1_PLUS, lambda s: (s["running"] or {}).get("kind") == "jog", "homing")
    time.sleep(0.5)
    page.mouse.up()
    ended = cell.wait(lambda s: s["running"] is None, "the session ended", timeout=10.0)
    assert not ended["initialized"]
    session = ended["programs"][-1]
    assert session["kind"] == "jog" and session["state"] == "aborted", session
    page.wait_for_selector("#messages >> text=homing moves only while a jog button is held", timeout=LOAD * 1000)
    _give_back(page)
    page.close()


@pytest.mark.long  # (a long wall-clock test: started first, not left for the run's tail)
def test_holding_a_jog_button_moves_the_robot_and_releasing_it_stops_it(cell, tmp_path):
    page = cell.open()
    _take(page)
    pad = page.locator("#pad-axes").bounding_box()
    if not cell.status()["initialized"]:  # (held through homing: the jog goes on when it has ended)
        _press_until(cell, page, A1_MINUS, lambda s: (s["jog"] or {}).get("active"), "homed and jogging")
        page.mouse.up()
    page.wait_for_selector("#jog-note:text('hold a button to move')", timeout=LOAD * 1000)
    # (nothing above the pad changes its size with the robot's state: a button that moved from
    # under the held pointer would be released)
    assert page.locator("#pad-axes").bounding_box() == pad
    for _ in range(4):  # (a hold the deadman cut short on a stalled host is held again)
        stalls = _stalls(cell, page)
        samples, released = _hold(cell, page, A1_PLUS, 1.0)
        if _stalls(cell, page) == stalls:
            break
    held = [q for at, q in samples if at < released]
    assert held[-1][0] - held[0][0] > 1.0, "A1 did not move while its button was held"
    assert all(abs(a - b) < STILL for a, b in zip(held[-1][1:], held[0][1:])), "another axis moved"
    assert _still_after(samples, released) < AT_REST_WITHIN, "the arm moved on after the release"
    state = page.evaluate("window.__pendant.st")
    page.wait_for_selector("#messages >> text=jog A1+ stopped: released", timeout=LOAD * 1000)
    timings = page.evaluate("window.__pendant.st.timings")
    print(f"pointer event to request sent (ms): press {timings['press']}, release {timings['release']}")
    assert timings["press"] and timings["release"], state
    page.screenshot(path=str(tmp_path / "pendant-jogging.png"))
    # leaving the button releases it, and so does the page's losing the focus; a page that
    # stops its heartbeats without a release (hung) has its jog stopped all the same
    leave = _centre(page, "#jog-note")
    for end, why in ((lambda p: p.mouse.move(*leave), "pointerleave"),
                     (lambda p: p.evaluate("window.dispatchEvent(new Event('blur'))"), "the page lost the focus"),
                     (lambda p: p.evaluate("clearInterval(window.__pendant.hold.timer)"), None)):
        for _ in range(4):  # (a jog the deadman stopped on a stalled host before its end: again)
            _press_until(cell, page, A1_MINUS, lambda s: (s["jog"] or {}).get("active") == "A1-", "jogging")
            stalls = _stalls(cell, page)
            releases = page.evaluate("window.__pendant.releases.length")
            time.sleep(0.2)
            ended = time.monotonic()
            end(page)
            stopped = cell.wait(lambda s: not (s["jog"] or {}).get("active"), "stopped", timeout=5.0)
            took = time.monotonic() - ended
            if why is None or _stalls(cell, page) == stalls:
                break
            page.mouse.up()
        assert took < AT_REST_WITHIN + 0.5, stopped
        if why is None:  # (the pendant's watch released it, or the server's heartbeat timeout stopped it)
            assert re.search("released|no heartbeat", stopped["jog"]["reason"]), stopped
        else:
            assert page.evaluate("window.__pendant.releases.at(-1).why") == why
            assert page.evaluate("window.__pendant.releases.length") == releases + 1
            assert stopped["jog"]["reason"] == "jog A1- stopped: released", stopped
        page.mouse.up()
    _give_back(page)
    _idle(cell)
    page.close()


def test_the_pause_button_pauses_a_running_program(cell):
    page = cell.open()
    _take(page)
    page.select_option("#programs", "slow.irl")
    page.click("#start")
    moving = cell.wait(lambda s: (s["running"] or {}).get("fsm") == "Move Robot"
                       and (s["running"] or {}).get("kind") == "program", "moving")
    program = moving["running"]["id"]
    page.wait_for_selector("#pause:not([disabled])", timeout=LOAD * 1000)
    page.click("#pause")
    cell.wait(lambda s: (s["running"] or {}).get("paused"), "paused")
    page.wait_for_selector("#program-line .paused", timeout=LOAD * 1000)
    page.wait_for_selector("#messages >> text=slow starts", timeout=LOAD * 1000)  # (its print)
    page.click("#abort")
    ended = cell.client.request("wait", {"program": program, "timeout": LOAD})
    assert ended["state"] == "aborted", ended
    _give_back(page)
    page.close()


@pytest.mark.long  # (a long wall-clock test: started first, not left for the run's tail)
def test_the_estop_of_a_page_without_control_stops_another_clients_program(cell):
    page = cell.open()
    other = cell.client
    other.request("control", {"take": True, "name": "cell PLC"})
    try:
        job = other.request("submit", {"object": objcode(cell.programs / "slow.irl", cell.server.spec),
                                        "name": "slow"})["program"]
        # (running: homing again, as the abort of the test before ended its cycle early, or moving)
        cell.wait(lambda s: (s["running"] or {}).get("id") == job, "running")
        page.wait_for_selector("#control-pill.other:text('cell PLC')", timeout=LOAD * 1000)
        assert page.is_disabled("#pause") and page.is_disabled(A1_PLUS)
        page.click("#estop")
        ended = other.request("wait", {"program": job, "timeout": LOAD})
        assert ended["state"] in TERMINAL and ended["state"] != "completed", ended
        assert "emergency stop" in (ended.get("fault") or ""), ended
    finally:
        other.request("control", {"take": False})
    page.close()

