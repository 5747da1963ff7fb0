"""`irl view`, measured as a user meets it (issue 30's figures), in Debian's headless Chromium.

1. How long `irl view PROG.irl` takes to show a program: from the command's start to the URL
   printed, and to the page drawn in the browser (its source panel and the arm's canvas),
   against `irl check PROG.irl` of the same program in the same run (the view runs the
   same offline check, with its setpoints kept, and starts the page).
2. Live mode's frame rate while a program runs: a wall-clock `irl serve`, `irl view
   --endpoint`, a program moving the arm; the times a second the view posed the arm (what
   the page says) and the frames a second the browser drew (requestAnimationFrame, counted in
   the page; software WebGL here: a GPU draws more), with the telemetry's 100 samples a second
   as the reference.
3. A recording's size per minute of the robot's clock: `irl run PROG --record X.mcap
   --report X.csv`, against the report's own size.

Run: .venv/bin/python benchmarks/view.py [--program programs/palletize.irl]
"""
from __future__ import annotations

import argparse
import os
import re
import signal
import socket
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
IRL = str(Path(sys.executable).with_name("irl"))
ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
FLAGS = ["--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader", "--disable-background-networking",
         "--disable-component-update", "--disable-sync", "--no-first-run"]
MOVING = """program moving;
system_specification "SPEC";
var k : integer;
seq
  for k := 1 to 3 do
    move ptp joint(mainjoint(40, 0, -40, 0, 30, 0)) speed_ptp := 0.3;
    move ptp joint(mainjoint(-40, 20, 20, 0, -30, 0)) speed_ptp := 0.3;
  endfor;
endseq
endprogram;
"""


def port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def start_view(*args) -> tuple[subprocess.Popen, str, float]:
    t0 = time.perf_counter()
    proc = subprocess.Popen([IRL, "view", *args, "--port", str(port())], cwd=ROOT, env=ENV, text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT)
    for line in proc.stdout:
        found = re.search(r"(http://127\.0\.0\.1:\d+/)", line)
        if found:
            return proc, found.group(1), time.perf_counter() - t0
    raise SystemExit(f"irl view ended: {proc.wait()}")


def stop(proc: subprocess.Popen) -> None:
    proc.send_signal(signal.SIGTERM)
    proc.wait(15)


def show_program(browser, program: str) -> None:
    t0 = time.perf_counter()
    subprocess.run([IRL, "check", program], cwd=ROOT, env=ENV, capture_output=True)
    check = time.perf_counter() - t0
    t0 = time.perf_counter()
    proc, url, printed = start_view(program)
    page = browser.new_page(viewport={"width": 1280, "height": 800})
    page.goto(url)
    page.wait_for_selector(".irl-source", timeout=120_000)
    page.wait_for_timeout(100)
    drawn = time.perf_counter() - t0
    stop(proc)
    page.close()
    print(f"show {program}: URL printed after {printed:.2f} s, page drawn after {drawn:.2f} s; "
          f"irl check of it {check:.2f} s (ratio {drawn / check:.2f})")


def live_rate(browser, seconds: float) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        spec = Path(tmp) / "lola15_soft.spc"
        spec.write_text((ROOT / "programs/lola15.spc").read_text().replace('servo_miss_policy = "firm"',
                                                                            'servo_miss_policy = "soft"'))
        prog = Path(tmp) / "moving.irl"
        prog.write_text(MOVING.replace("SPEC", spec.name))
        endpoint, telemetry = f"tcp://127.0.0.1:{port()}", f"tcp://127.0.0.1:{port()}"
        server = subprocess.Popen([IRL, "serve", "--spec", str(spec), "--state-dir", tmp, "--endpoint", endpoint,
                                   "--telemetry", telemetry], cwd=ROOT, env=ENV, stdout=subprocess.DEVNULL,
                                  stderr=subprocess.DEVNULL)
        time.sleep(2.0)
        proc, url, _ = start_view("--endpoint", endpoint, "--telemetry", telemetry)
        page = browser.new_page(viewport={"width": 1280, "height": 800})
        page.goto(url)
        page.wait_for_selector("text=live", timeout=60_000)
        page.evaluate("window.__frames = 0; (function f() { window.__frames++; requestAnimationFrame(f); })()")
        subprocess.run([IRL, "submit", str(prog), "--endpoint", endpoint], cwd=ROOT, env=ENV, capture_output=True)
        page.wait_for_selector("text=Move Robot", timeout=60_000)
        page.wait_for_timeout(1000)
        f0, t0 = page.evaluate("window.__frames"), time.perf_counter()
        posed = []
        while time.perf_counter() - t0 < seconds:
            page.wait_for_timeout(1000)
            found = re.search(r"posed (\d+) times/s", page.inner_text("body"))
            if found:
                posed.append(int(found.group(1)))
        fps = (page.evaluate("window.__frames") - f0) / (time.perf_counter() - t0)
        print(f"live, while a program runs: the arm posed {sorted(posed)[len(posed) // 2] if posed else 0} times/s "
              f"(median of {len(posed)} readings; the telemetry: 100 samples/s), the browser drew {fps:.1f} "
              "frames/s (software WebGL)")
        stop(proc)
        server.send_signal(signal.SIGTERM)
        server.wait(30)


def recording_size(program: str) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        mcap, csv = Path(tmp) / "run.mcap", Path(tmp) / "run.csv"
        done = subprocess.run([IRL, "run", program, "--record", str(mcap), "--report", str(csv)], cwd=ROOT, env=ENV,
                              capture_output=True, text=True)
        if done.returncode != 0 or not mcap.exists():
            print(f"recording: irl run --record failed ({done.returncode}): {done.stderr.strip()[:300]}")
            return
        last = csv.read_text().rstrip().rsplit("\n", 1)[-1].split(",")[0]
        minutes = float(last) / 60.0
        print(f"recording of {program}: {mcap.stat().st_size / minutes / 1e6:.2f} MB per minute of the robot's clock "
              f"({mcap.stat().st_size / 1e6:.2f} MB for {minutes * 60:.1f} s); its report (CSV): "
              f"{csv.stat().st_size / minutes / 1e6:.2f} MB per minute")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--program", default="programs/palletize.irl")
    parser.add_argument("--seconds", type=float, default=5.0, help="how long live mode is measured")
    args = parser.parse_args()
    from playwright.sync_api import sync_playwright

    chromium = "/usr/bin/chromium"
    with sync_playwright() as p:
        browser = p.chromium.launch(executable_path=chromium, args=FLAGS)
        show_program(browser, args.program)
        live_rate(browser, args.seconds)
        browser.close()
    recording_size(args.program)


if __name__ == "__main__":
    main()
