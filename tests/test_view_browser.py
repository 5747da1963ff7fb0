"""``irl view`` in a real browser: Debian's headless Chromium, driven by Playwright.

Each test starts ``irl view`` as a user does (a process of its own, the URL it prints), opens
the page, and judges it from screenshots of the 3D canvas and from the page's DOM: the arm
is drawn (coloured pixels in the canvas), it moves when the slider moves (replay) and when
the robot moves (live), and the marked source line follows the program. Without Chromium
the tests are skipped, except where ``IRL_REQUIRE_BROWSER=1`` (CI, whose .ci/run installs
it): there they fail (tests/browser.py).
"""
from __future__ import annotations

import io
import time

import pytest

from tests.browser import LOAD, View, browser  # noqa: F401 (browser: the fixture)
from tests.conftest import SPEC_PATH, ServerProcess, objcode, run_irl


#: A program of three slow moves, a line each: about 10 s of the robot's clock per move, so
#: that on the simulated clock (many times faster than the wall's) each move still lasts
#: several of the view's 30 poses a second, whatever the machine.
MOVING = """program moving;
system_specification "lola15.spc";
seq
  move ptp joint(mainjoint(40, 0, -40, 0, 30, 0)) speed_ptp := 0.05;
  move ptp joint(mainjoint(-40, 20, 20, 0, -30, 0)) speed_ptp := 0.05;
  move ptp joint(mainjoint(0, -20, 40, 30, 45, 0)) speed_ptp := 0.05;
endseq
endprogram;
"""


#: A script that keeps, in the page, every line marked current (window.__lines), in order: from
#: each source box's trail (its data-trail, the last marks the view showed, with their running
#: count: a transport that coalesced quick updates still gives each one), and from each mutation
#: record's added nodes, so that marks a starved page applied in one task
#: (several source boxes between two callbacks) are each seen; 0 for a box without a mark.
WATCH_LINES = """() => {
  window.__lines = [];
  let count = 0;  // the running count of the last mark taken from a box's data-trail
  const push = (n) => { if (window.__lines[window.__lines.length - 1] !== n) window.__lines.push(n); };
  const take = (node) => {  // a source box: every mark of its trail not taken yet, in order
    if (!(node instanceof Element)) return false;
    const box = node.classList.contains("irl-source") ? node : node.querySelector(".irl-source");
    if (!box) return false;
    for (const item of (box.dataset.trail || "").split(" ").filter((t) => t)) {
      const [k, n] = item.split(":").map((t) => parseInt(t));
      if (k > count) { count = k; push(n); }
    }
    return true;
  };
  const now = () => {
    const box = document.querySelector(".irl-source");
    if (box) take(box);
  };
  new MutationObserver((records) => {
    let seen = false;
    for (const r of records) for (const node of r.addedNodes) seen = take(node) || seen;
    if (!seen) now();
  }).observe(document.body, {subtree: true, childList: true, characterData: true, attributes: true});
  now();
}"""


def _open(browser, url: str):
    page = browser.new_page(viewport={"width": 960, "height": 640})
    page.goto(url)
    page.wait_for_selector("text=Connected", timeout=LOAD * 1000)
    # (the page's notices, e.g. that WebGL runs in software here, are drawn over the canvas)
    page.add_style_tag(content="[role=alert], .mantine-Notifications-root, .mantine-Notification-root "
                               "{ display: none !important; }")
    return page


def _canvas(page):
    """The 3D canvas as RGB pixels."""
    import numpy as np
    from matplotlib.image import imread

    png = page.locator("canvas").first.screenshot()
    return (imread(io.BytesIO(png), format="png")[..., :3] * 255).astype(np.int16)


def _arm_pixels(img) -> int:
    """Pixels of the arm's colours (orange links, dark joints), not of the white ground and grey grid."""
    r, g, b = img[..., 0], img[..., 1], img[..., 2]
    orange = (r > 150) & (r - b > 60) & (g > 60)
    return int(orange.sum())


def _drawn(page):
    """The canvas once the arm is on it (a loaded host may take a while to bring the page
    its first sample and render it): polled up to LOAD seconds; the last one seen."""
    deadline = time.monotonic() + LOAD
    while True:
        img = _canvas(page)
        if _arm_pixels(img) > 500 or time.monotonic() > deadline:
            return img
        _settle(page, 0.2)


def _settle(page, seconds: float = 1.0) -> None:
    page.wait_for_timeout(seconds * 1000)


def _set_time(page, t: float) -> None:
    box = page.get_by_role("textbox").or_(page.locator("input[type=number]")).last
    box.fill(f"{t:g}")
    box.press("Enter")


@pytest.mark.long  # (a long wall-clock test: started first, not left for the run's tail)
def test_program_paths_and_the_arm(browser, tmp_path):
    """A program (a new user's first one, with moves the robot would refuse): the arm drawn,
    the refused moves listed with their lines, a move picked from the list marks its line
    and says why it is refused, and the slider moves the arm along the program."""
    view = View("tests/motion_check/first_hour.irl")
    try:
        page = _open(browser, view.url)
        page.wait_for_selector(".irl-source", timeout=LOAD * 1000)
        _settle(page, 2.0)
        first = _drawn(page)
        assert _arm_pixels(first) > 500, "no arm in the canvas"
        assert "20 moves" in page.inner_text("body") and "5 refused" in page.inner_text("body")
        refused = {int(e.get_attribute("data-line")) for e in page.query_selector_all(".irl-refused [data-line]")}
        assert refused == {16, 19, 23, 29, 33}
        page.get_by_role("textbox", name="move").or_(page.get_by_label("move")).first.click()
        page.get_by_role("option", name="2: line 16, ptp (refused)").click()
        page.wait_for_selector("#current-line[data-line='16']", timeout=LOAD * 1000)
        assert "refused" in page.inner_text("body")
        _set_time(page, 8.0)
        _settle(page)
        later = _canvas(page)
        assert abs(later - first).sum(axis=2).astype(bool).sum() > 500, "the arm did not move with the slider"
    finally:
        assert view.stop() == 0


@pytest.mark.long  # (a long wall-clock test: started first, not left for the run's tail)
def test_replay_follows_the_slider(browser, tmp_path):
    report = tmp_path / "test.csv"
    done = run_irl("run", "programs/test.irl", "--report", report, "--report-columns", "+move")
    assert done.returncode == 0, done.stderr
    view = View(report, "--spec", SPEC_PATH)
    try:
        page = _open(browser, view.url)
        page.wait_for_selector(".irl-timeline", timeout=LOAD * 1000)
        _settle(page, 2.0)
        shots, lines = [], []
        for t in (0.5, 12.0, 20.0):
            _set_time(page, t)
            _settle(page)
            shots.append(_drawn(page))
            lines.append(page.inner_text("body"))
        assert _arm_pixels(shots[0]) > 500
        assert abs(shots[1] - shots[0]).sum(axis=2).astype(bool).sum() > 500, "the arm did not follow the slider"
        assert "Calibrate" in lines[0] or "Start" in lines[0]
        assert "Move Robot" in lines[1]
    finally:
        assert view.stop() == 0


@pytest.mark.long  # (a long wall-clock test: started first, not left for the run's tail)
def test_live_follows_the_robot(browser, tmp_path):
    # the simulated clock: the view follows the telemetry whatever its pace (a wall-clock loop
    # would spend 20 s of a core on the homing and the moves, and take from the tests that
    # count its deadlines)
    (tmp_path / "lola15.spc").write_text(SPEC_PATH.read_text(encoding="utf-8"), encoding="utf-8")
    server = ServerProcess(tmp_path / "server", tmp_path / "state").start()
    view = None
    try:
        view = View("--endpoint", server.endpoint, "--telemetry", server.telemetry)
        page = _open(browser, view.url)
        page.wait_for_selector("text=live", timeout=LOAD * 1000)
        _settle(page, 1.5)
        before = _drawn(page)
        assert _arm_pixels(before) > 500, "the arm was not drawn"
        client = server.client()
        program = tmp_path / "moving.irl"
        program.write_text(MOVING, encoding="utf-8")
        source = MOVING
        # every line the page marks, as it marks it (the page notes them itself: polling it from
        # here would miss a line while a busy machine renders slowly), from before the program
        # starts (a loaded host could mark the first move's line before a watch set up after it)
        page.evaluate(WATCH_LINES)
        job = client.request("submit", {"object": objcode(program), "name": "moving.irl",
                                        "source": source})["program"]
        deadline = time.monotonic() + LOAD
        moved = 0
        while time.monotonic() < deadline:
            if client.request("status", {"program": job})["state"] not in ("queued", "running"):
                break
            if moved <= 500 and page.evaluate("window.__lines.length") > 0:  # (moving: where is the arm?)
                moved = int(abs(_canvas(page) - before).sum(axis=2).astype(bool).sum())
            _settle(page, 0.2)
        # the page shows each line the program passed for a while (runtime.view.live.MARK_HOLD), so
        # a loaded host's page may still be behind the program: until it shows the idle robot
        deadline = time.monotonic() + LOAD
        while page.evaluate("window.__lines[window.__lines.length - 1]") != 0 and time.monotonic() < deadline:
            _settle(page, 0.2)
        moved = max(moved, int(abs(_canvas(page) - before).sum(axis=2).astype(bool).sum()))
        lines = [n for n in page.evaluate("window.__lines") if n]
        assert moved > 500, "the arm did not move with the robot"
        moves = [n for n in lines if n in (4, 5, 6)]  # (the program's three moves, in order)
        assert moves == [4, 5, 6], f"the marked line did not follow the program: {lines}\n{page.inner_text('body')}"
        server.stop()
        page.wait_for_selector("text=connection lost", timeout=LOAD * 1000)
    finally:
        if view is not None:
            assert view.stop() == 0
        server.stop()
