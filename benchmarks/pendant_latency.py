"""The pendant's hold-to-run latency in headless Chromium against a wall-clock server in T1.

Figures, over N presses of a jog button (A1, held 0.4 s, alternately + and -):
  pointer down -> the jog request sent to the server (the page's pointer event to the
  pendant's send, the same machine's clock), p50 and max;
  pointer up -> the release request sent, p50 and max;
  pointer down -> the arm moving, and pointer up -> the arm at rest (the measured position
  in ``status``, polled every 20 ms by a client of the benchmark's own: a bound, not an
  exact figure), p50 and max; the goal for the last: at most 0.5 s (docs/protocol.md, jog).
The robot homes first (a held button, about 13 s in T1). Needs Chromium (apt-get install
chromium) and Playwright (the test extras).
Run: .venv/bin/python benchmarks/pendant_latency.py [--presses N]
"""
from __future__ import annotations

import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from runtime.client.client import Client, ClientError  # noqa: E402
from _stats import LOLA15, arguments, free_port, percentile  # noqa: E402

IRL = [str(Path(sys.executable).with_name("irl"))]
FLAGS = ["--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-first-run", "--disable-dev-shm-usage"]
STILL = 0.005  # deg: a change of the measured position that is motion (an encoder count is 1/1820 deg)


def start(directory: Path) -> tuple[subprocess.Popen, subprocess.Popen, str, str]:
    spec = directory / "lola15_soft.spc"
    spec.write_text(LOLA15.read_text(encoding="utf-8").replace('servo_miss_policy = "firm"',
                                                               'servo_miss_policy = "soft"'), encoding="utf-8")
    endpoint, telemetry = f"tcp://127.0.0.1:{free_port()}", f"tcp://127.0.0.1:{free_port()}"
    server = subprocess.Popen([*IRL, "serve", "--spec", str(spec), "--mode", "t1", "--state-dir", str(directory),
                               "--endpoint", endpoint, "--telemetry", telemetry], cwd=ROOT,
                              stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    probe = Client(endpoint, timeout=0.5)
    for _ in range(40):
        try:
            probe.request("hello")
            break
        except ClientError:
            time.sleep(0.1)
    probe.close()
    view = subprocess.Popen([*IRL, "view", "--endpoint", endpoint, "--telemetry", telemetry, "--port",
                             str(free_port())], cwd=ROOT, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    for line in view.stdout:
        found = re.search(r"the pendant: (\S+)", line)
        if found:
            return server, view, endpoint, found.group(1)
    raise SystemExit("irl view did not start")


def watch(client: Client, until: float) -> list[tuple[float, list]]:
    samples = []
    while time.time() < until:
        samples.append((time.time(), client.request("status")["position"]))
        time.sleep(0.02)
    return samples


def first_after(samples, t: float, moving: bool) -> float | None:
    """The first sample after ``t`` that moved from the one before (``moving``), or the
    first after which nothing moved any more."""
    changes = [(b[0], max(abs(x - y) for x, y in zip(a[1], b[1])) > STILL) for a, b in zip(samples, samples[1:])]
    if moving:
        return next((at - t for at, moved in changes if at >= t and moved), None)
    last = max((at for at, moved in changes if moved), default=t)
    return max(0.0, last - t)


def main() -> None:
    args = arguments(__doc__, presses=20).parse_args()
    chromium = shutil.which("chromium") or shutil.which("chromium-browser")
    if chromium is None:
        raise SystemExit("needs Chromium: apt-get install chromium")
    from playwright.sync_api import sync_playwright

    with tempfile.TemporaryDirectory() as tmp:
        server, view, endpoint, url = start(Path(tmp))
        client = Client(endpoint)
        try:
            with sync_playwright() as p:
                browser = p.chromium.launch(executable_path=chromium, args=FLAGS)
                page = browser.new_page(viewport={"width": 1280, "height": 900})
                page.goto(url + "?view=off")
                page.wait_for_selector("#control-pill:not(:text-is('control: ?'))")
                page.fill("#name", "benchmark")
                page.click("#take")
                page.wait_for_selector("#control-pill.you")
                moves, rests = [], []
                for k in range(args.presses + 1):
                    box = page.locator(f'button.jog[data-axis="A1"][data-dir="{1 if k % 2 else -1}"]').bounding_box()
                    page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
                    down = time.time()
                    page.mouse.down()
                    if k == 0:  # (homing first, held)
                        while not (client.request("status").get("jog") or {}).get("active"):
                            time.sleep(0.1)
                        page.mouse.up()
                        watch(client, time.time() + 2.5)
                        continue
                    samples = watch(client, down + 0.4)
                    page.mouse.up()
                    samples += watch(client, time.time() + 1.0)
                    released = page.evaluate("window.__pendant.releases.at(-1).at") / 1000.0
                    moves.append(first_after(samples, down, True))
                    rests.append(first_after(samples, released, False))
                timings = page.evaluate("window.__pendant.st.timings")
                browser.close()
        finally:
            client.close()
            for process in (view, server):
                process.send_signal(signal.SIGTERM)
                process.wait(15)
    press, release = timings["press"][1:], timings["release"][1:]  # (the first: homing's)
    moves = [m for m in moves if m is not None]

    def figure(values, scale=1.0, unit="ms") -> str:
        return f"p50 {percentile(values, 0.5) * scale:6.1f} {unit}, max {max(values) * scale:6.1f} {unit}"
    print(f"{len(press)} presses of a jog button in headless Chromium (A1, held 0.4 s, T1, wall clock):")
    print(f"  pointer down -> jog request sent:     {figure(press)}")
    print(f"  pointer up   -> release request sent: {figure(release)}")
    print(f"  pointer down -> the arm moving:       {figure(moves, 1000.0)} (status polled every 20 ms)")
    print(f"  pointer up   -> the arm at rest:      {figure(rests, 1000.0)} (goal: at most 500 ms)")


if __name__ == "__main__":
    main()
