"""The per-axis kernels: compiled (mypyc) and source give bit-identical results, the
runtime picks the compiled build only when it matches the source, and whole runs are the
same byte for byte either way."""
from __future__ import annotations

import hashlib
import json
import math
import os
import struct
import subprocess
import sys
import types
from pathlib import Path

import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from runtime import accel
from runtime import kernels as source

from conftest import ROOT, examples
COMPILED = accel._compiled_module()
SETTINGS = settings(max_examples=examples(300), deadline=None, derandomize=True, database=None)
needs_build = pytest.mark.skipif(COMPILED is None, reason="no compiled kernels (test_the_build_compiled_the_kernels says why)")


def bits(values) -> list:
    """Floats as their bit patterns (NaN == NaN, -0.0 != 0.0); other values as they are."""
    return [struct.pack("<d", v) if isinstance(v, float) else v for v in values]


def test_the_build_compiled_the_kernels():
    """pip install -e . compiles runtime/kernels.py; the runtime runs that build."""
    if os.environ.get(accel.ENV, "").strip().lower() == "python":
        assert accel.kernels is source and not accel.COMPILED
        return
    assert COMPILED is not None, ("runtime/_kernels_c was not built: reinstall (pip install -e .) on a machine "
                                  "with a C compiler, or set IRL_KERNELS=python to test the source alone")
    assert COMPILED.SOURCE_SHA256 == accel.source_digest(), "stale build: pip install -e ."
    assert accel.kernels is COMPILED and accel.COMPILED
    assert accel.DESCRIPTION == "compiled (mypyc)"
    assert Path(COMPILED.__file__).suffix in (".so", ".pyd")


# ---- selection -------------------------------------------------------------------------

def fake_build(digest: str) -> types.ModuleType:
    module = types.ModuleType("runtime._kernels_c")
    module.SOURCE_SHA256 = digest
    return module


def test_select_takes_a_build_of_this_source():
    build = fake_build("abc")
    assert accel.select("", build, "abc") == (build, "compiled (mypyc)")
    assert accel.select("auto", build, "abc")[0] is build


def test_select_runs_the_source_when_asked_or_without_a_build():
    assert accel.select("python", fake_build("abc"), "abc") == (source, "python (IRL_KERNELS=python)")
    chosen, why = accel.select("", None, "abc")
    assert chosen is source and "no compiled build" in why and "pip install -e ." in why


def test_select_ignores_a_stamped_copy_that_was_never_compiled():
    leftover = fake_build("abc")
    leftover.__file__ = "/somewhere/runtime/_kernels_c.py"
    assert accel.select("", leftover, "abc")[0] is source


def test_select_refuses_a_stale_build_with_a_warning():
    with pytest.warns(UserWarning, match="stale"):
        chosen, why = accel.select("", fake_build("old"), "new")
    assert chosen is source and "stale" in why and "kernels.py changed" in why and "pip install -e ." in why


def test_select_warns_about_an_unknown_choice():
    build = fake_build("abc")
    with pytest.warns(UserWarning, match="IRL_KERNELS='fast'"):
        assert accel.select("fast", build, "abc")[0] is build


def test_source_digest_is_the_file_hash(tmp_path):
    f = tmp_path / "k.py"
    f.write_bytes(b"x = 1\n")
    assert accel.source_digest(f) == hashlib.sha256(b"x = 1\n").hexdigest()
    assert accel.source_digest(f) != accel.source_digest()


# ---- compiled == source, bit for bit ----------------------------------------------------

finite = st.floats(-1e4, 1e4, allow_nan=False, allow_infinity=False)
anything = st.one_of(finite, st.sampled_from([math.nan, math.inf, -math.inf, 0.0, -0.0]))


@st.composite
def drive_cases(draw):
    n = draw(st.integers(1, 6))
    floats = lambda: draw(st.lists(finite, min_size=n, max_size=n))  # noqa: E731
    commands = tuple(draw(st.lists(anything, min_size=n, max_size=n)))
    vmax = [abs(v) + 1.0 for v in floats()]
    lo = floats()
    safe_lo = [min(a, b) for a, b in zip(lo, floats())]
    safe_hi = [max(a, b) for a, b in zip(lo, floats())]
    constants = tuple((m, -m, b, o, draw(st.floats(1.0, 1e5)), draw(st.integers(-10**6, 10**6)))
                      for m, b, o in zip(vmax, floats(), floats()))
    dt = draw(st.sampled_from([0.001, 0.005, 0.0001]))
    tau = draw(st.floats(1e-4, 0.1))
    return dt, math.exp(-dt / tau), tau * (1 - math.exp(-dt / tau)), commands, floats(), floats(), \
        safe_lo, safe_hi, constants


def run_drive(module, case):
    dt, decay, gain, commands, xs, vs, safe_lo, safe_hi, constants = case
    xs, vs, counts, calls = list(xs), list(vs), [0] * len(xs), []

    def edges(i: int, x: float, v: float) -> tuple[float, float]:
        calls.append((i, x, v))
        return max(min(x, 100.0), -100.0), v * 0.5

    module.drive_step(dt, decay, gain, commands, xs, vs, safe_lo, safe_hi, constants, counts, edges)
    return bits(xs), bits(vs), counts, [(i, *bits((x, v))) for i, x, v in calls]


@needs_build
@SETTINGS
@given(drive_cases())
def test_drive_step_compiled_equals_source(case):
    assert run_drive(COMPILED, case) == run_drive(source, case)


@st.composite
def servo_cases(draw):
    """Servo-like magnitudes (so that most commands are not saturated), some axes still,
    segments with and without breakpoints."""
    n = draw(st.integers(1, 6))
    reals = lambda lo, hi: draw(st.lists(st.floats(lo, hi), min_size=n, max_size=n))  # noqa: E731
    still = draw(st.lists(st.booleans(), min_size=n, max_size=n))
    segments = []
    for s, p in zip(still, reals(-180, 180)):
        if s:
            segments.append((p, 0.0, 0.0, 0.0, 0.0, 0.0, source.NO_BREAK, 0.0, 0.0, source.NO_BREAK, 0.0, 0.0))
        else:
            c = [draw(st.floats(-5, 5)) for _ in range(5)]
            s1, s2 = sorted(draw(st.sampled_from([source.NO_BREAK, 0.0, 0.3, 0.7, 1.0])) for _ in range(2))
            segments.append((p, *c, s1, draw(st.floats(-1, 1)), draw(st.floats(-1, 1)), s2, draw(st.floats(-1, 1)),
                             draw(st.floats(-1, 1))))
    s = draw(st.floats(-0.2, 1.2))
    inv_h = draw(st.sampled_from([0.0, 200.0, 1000.0]))
    position = tuple(c[0] + e for c, e in zip(segments, reals(-3, 3)))
    vmax = tuple(reals(1.0, 500.0))
    return (tuple(segments), s, inv_h, position, reals(-1, 1), vmax, tuple(-v for v in vmax), draw(st.floats(0, 100)),
            draw(st.floats(0, 10)), draw(st.sampled_from([0.001, 0.0005])))


def run_servo(module, case):
    segments, s, inv_h, position, integral, vmax, vmin, kp, ki, dt = case
    integral, out = list(integral), [0.0] * len(segments)
    worst = module.servo_law(segments, s, inv_h, position, integral, vmax, vmin, kp, ki, dt, out)
    return bits([worst]), bits(integral), bits(out)


@needs_build
@SETTINGS
@given(servo_cases())
def test_servo_law_compiled_equals_source(case):
    assert run_servo(COMPILED, case) == run_servo(source, case)


@SETTINGS
@given(servo_cases())
def test_servo_law_evaluates_the_segments_as_the_interpolator_does(case):
    """The reference inside servo_law is segment_position / segment_velocity, bit for bit
    (the interpolator's sample() and the servo's reference property use those)."""
    segments, s, inv_h, position, integral, vmax, vmin, kp, ki, dt = case
    module = accel.kernels
    out = [0.0] * len(segments)
    integral = list(integral)
    before = list(integral)
    module.servo_law(segments, s, inv_h, position, integral, (math.inf,) * len(out), (-math.inf,) * len(out), 1.0,
                     0.0, dt, out)
    for c, x, u, i0, i1 in zip(segments, position, out, before, integral):
        e = module.segment_position(c, s) - x
        assert bits([u]) == bits([module.segment_velocity(c, s, inv_h) + 1.0 * e + 0.0 * i0])
        assert bits([i1]) == bits([i0 + e * dt])


@st.composite
def setpoint_pairs(draw):
    """Two setpoints of one axis (positions, velocities, accelerations), the period and
    the limits: from a motion-like scale to extremes (NaN, infinities, zeros)."""
    h = draw(st.sampled_from([0.005, 0.001, 0.01]))
    p0 = draw(st.floats(-360, 360))
    v0, v1 = draw(st.floats(-200, 200)), draw(st.floats(-200, 200))
    a0, a1 = draw(st.floats(-2000, 2000)), draw(st.floats(-2000, 2000))
    p1 = p0 + h * 0.5 * (v0 + v1) + draw(st.floats(-1e-3, 1e-3))
    values = [p0, v0, a0, p1, v1, a1]
    if draw(st.booleans()):
        values[draw(st.integers(0, 5))] = draw(anything)
    limits = draw(st.sampled_from([(156.0, 400.0, 4000.0), (math.inf,) * 3, (1.0, 1.0, 1.0)]))
    return (*values, h, *limits)


@needs_build
@SETTINGS
@given(setpoint_pairs())
def test_segment_compiled_equals_source(case):
    assert bits(COMPILED.segment(*case)) == bits(source.segment(*case))
    p0, v0, a0, p1, v1, a1, h = case[:7]
    assert bits(COMPILED.hermite_segment(p0, v0, p1, v1, h)) == bits(source.hermite_segment(p0, v0, p1, v1, h))
    c = source.segment(*case)
    for s in (0.0, 0.25, 0.999, 1.0):
        assert bits([COMPILED.segment_position(c, s), COMPILED.segment_velocity(c, s, 1 / h),
                     COMPILED.segment_acceleration(c, s, 1 / h)]) == \
            bits([source.segment_position(c, s), source.segment_velocity(c, s, 1 / h),
                  source.segment_acceleration(c, s, 1 / h)])


@st.composite
def estimator_cases(draw):
    n = draw(st.integers(1, 6))
    floats = lambda: draw(st.lists(finite, min_size=n, max_size=n))  # noqa: E731
    counts = tuple(draw(st.lists(st.integers(-10**8, 10**8), min_size=n, max_size=n)))
    scale = tuple(1.0 / draw(st.floats(1.0, 1e5)) for _ in range(n))
    return counts, scale, floats(), floats(), floats(), draw(st.sampled_from([0.001, 0.005])), \
        draw(st.floats(0.01, 1.9)), draw(st.floats(0.01, 100.0))


def run_estimator(module, case):
    counts, scale, offset, xs, vs, dt, alpha, beta_dt = case
    xs, vs, measured = list(xs), list(vs), [0.0] * len(xs)
    module.alpha_beta(counts, scale, offset, xs, vs, dt, alpha, beta_dt, measured)
    return bits(xs), bits(vs), bits(measured)


@needs_build
@SETTINGS
@given(estimator_cases())
def test_alpha_beta_compiled_equals_source(case):
    assert run_estimator(COMPILED, case) == run_estimator(source, case)


@needs_build
@SETTINGS
@given(st.integers(1, 6).flatmap(lambda n: st.tuples(
    st.lists(anything, min_size=n, max_size=n), st.lists(finite, min_size=n, max_size=n),
    st.lists(st.floats(0.0, 1e3), min_size=n, max_size=n))))
def test_clamp_commands_compiled_equals_source(case):
    command, compensation, limits = tuple(case[0]), case[1], tuple(case[2])
    assert bits(COMPILED.clamp_commands(command, compensation, limits)) == \
        bits(source.clamp_commands(command, compensation, limits))


@st.composite
def standstill_cases(draw):
    """A few ticks of standstill monitoring: still segments (the servo's reference at rest),
    positions within a few windows of them, some axes already in position."""
    n = draw(st.integers(1, 6))
    refs = draw(st.lists(st.floats(-180, 180), min_size=n, max_size=n))
    segments = tuple((p, 0.0, 0.0, 0.0, 0.0, 0.0, source.NO_BREAK, 0.0, 0.0, source.NO_BREAK, 0.0, 0.0) for p in refs)
    cpu = tuple(draw(st.floats(50.0, 20_000.0)) for _ in range(n))
    ticks = [tuple(r + draw(st.floats(-20.0, 20.0)) / k for r, k in zip(refs, cpu))
             for _ in range(draw(st.integers(1, 8)))]
    fixed = [draw(st.one_of(st.just(math.nan), st.floats(-1.0, 1.0).map(lambda d, r=r: r + d / 1000)))
             for r in refs]
    settle = tuple(draw(st.integers(0, 8)) * 0.001 for _ in range(n))
    return (segments, draw(st.floats(0.0, 1.0)), cpu, float(draw(st.integers(2, 10))),
            float(draw(st.integers(2, 20))), draw(st.sampled_from([0.001, 0.002, 0.02])), settle, ticks,
            draw(st.integers(0, 8)) * 0.001, fixed)


def run_standstill(module, case):
    segments, s, cpu, window, tolerance, hold, settle, ticks, deadline, fixed = case
    since, fixed, away, codes = [math.nan] * len(cpu), list(fixed), [0.0] * len(cpu), []
    for k, positions in enumerate(ticks):
        codes.append(module.standstill_check(positions, segments, s, cpu, window, tolerance, hold, settle, 0.0,
                                             k * 0.001, deadline, since, fixed, away))
    return codes, bits(since), bits(fixed), bits(away)


@needs_build
@SETTINGS
@given(standstill_cases())
def test_standstill_check_compiled_equals_source(case):
    assert run_standstill(COMPILED, case) == run_standstill(source, case)


def test_clamp_commands_clamps_and_passes_nan():
    out = accel.kernels.clamp_commands((5.0, -5.0, 0.5, math.nan), [0.0, 0.0, 0.25, 0.0], (1.0, 2.0, 1.0, 1.0))
    assert out[:3] == (1.0, -2.0, 0.75) and math.isnan(out[3])
    # the compensation (a drive's calibrated offset) is added after the clamp: at the limit too
    assert accel.kernels.clamp_commands((5.0, -5.0), [0.25, -0.25], (1.0, 2.0)) == (1.25, -2.25)


@needs_build
def test_integers_are_taken_as_floats_alike():
    """Callers may hand integer positions or commands: both implementations compute in floats."""
    for module in (COMPILED, source):
        assert module.clamp_commands((1, -3), [0, 0.5], (2.0, 2.0)) == (1.0, -1.5)


# ---- whole runs ------------------------------------------------------------------------

def run_paper_program(tmp_path: Path, kernels: str) -> tuple[dict, bytes, bytes]:
    report = tmp_path / f"{kernels}.csv"
    env = dict(os.environ, IRL_KERNELS=kernels)
    done = subprocess.run([sys.executable, "-m", "runtime.cli.main", "run", str(ROOT / "programs" / "test.irl"),
                           "--report", str(report), "--json"], capture_output=True, text=True, env=env,
                          cwd=ROOT, timeout=300, check=False)
    assert done.returncode == 0, done.stderr
    states = report.with_name(report.stem + ".states.csv")
    return json.loads(done.stdout), report.read_bytes(), states.read_bytes()


@needs_build
def test_the_paper_program_gives_the_same_bytes_compiled_and_as_python(tmp_path):
    compiled, report_c, states_c = run_paper_program(tmp_path, "auto")
    python, report_p, states_p = run_paper_program(tmp_path, "python")
    assert compiled["kernels"] == "compiled (mypyc)"
    assert python["kernels"] == "python (IRL_KERNELS=python)"
    assert report_c == report_p and states_c == states_p
    for key in ("states", "moves", "final_position", "max_following_error", "ticks", "fault"):
        assert compiled[key] == python[key], key
