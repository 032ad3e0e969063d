"""Property-based tests of the input boundary: random scene settings, command
lines and sweep values either work or are refused with a documented error that
names a parameter; never a traceback from NumPy or JAX, never a silent success
with non-finite values. Bounded: a few hundred cheap examples and a handful of
real runs (one compiled program)."""

import math
import os
import tempfile
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, event, example, given, settings
from hypothesis import strategies as st

import jaxmps
from jaxmps import _driver
from jaxmps.calibration._sweep import checked_batch
from jaxmps.cli import main

# Values of every awkward kind: NaN, infinities, zero, negative, huge, tiny,
# whole numbers, words, flags, None.
AWKWARD = st.one_of(
    st.sampled_from([math.nan, math.inf, -math.inf, 0, 0.0, -1.0, 1e300, 10**400]),
    st.floats(allow_nan=True, allow_infinity=True),
    st.floats(min_value=1e-3, max_value=1.0),
    st.integers(min_value=-(2**70), max_value=2**70),
    st.sampled_from(["abc", "", "semi_implicit", "explicit", "multigrid", "1e-3"]),
    st.booleans(),
    st.none(),
)
DEFAULTS = jaxmps.scenes.available()["hydrostatic"]
SETTINGS = sorted(DEFAULTS)


def _value_for(name: str):
    """An awkward value, or half the time one near the default (the default
    scaled by 0.7-1.5, a whole number for counts, or unchanged)."""
    default = DEFAULTS.get(name)
    if isinstance(default, bool) or not isinstance(default, (int, float)):
        near = st.just(default)
    elif isinstance(default, int):
        near = st.integers(max(1, default // 2), default * 2 if default else 3)
    else:
        near = st.floats(0.7, 1.5).map(lambda f: min(default * f, 0.99))
    return st.one_of(near, AWKWARD)


def _settings(max_size: int):
    """{name: value} of up to `max_size` hydrostatic settings."""
    pairs = st.sampled_from(SETTINGS).flatmap(
        lambda name: st.tuples(st.just(name), _value_for(name))
    )
    return st.lists(pairs, max_size=max_size).map(dict)


# Whatever is refused is refused with one of these, naming a parameter.
DOCUMENTED = (ValueError,)


def _names_a_parameter(message: str, names) -> bool:
    return any(name in message for name in names)


@pytest.fixture
def small_limit():
    """A particle limit that keeps any scene built here small (refused above)."""
    before = os.environ.get("JAXMPS_MAX_PARTICLES")
    os.environ["JAXMPS_MAX_PARTICLES"] = "4000"
    yield
    if before is None:
        del os.environ["JAXMPS_MAX_PARTICLES"]
    else:
        os.environ["JAXMPS_MAX_PARTICLES"] = before


@settings(
    max_examples=300,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(overrides=_settings(4))
# A subnormal spacing once overflowed the particle count (OverflowError).
@example(overrides={"spacing": 2.2250738585e-313})
# Half the largest double: the velocity scale sqrt(2 g H) overflowed and the
# time step came out 0 s, refused as `Params.dt` (not named by the user).
@example(overrides={"gravity": 8.98846567431158e307})
def test_scene_settings_build_or_are_refused_by_name(small_limit, overrides):
    try:
        case = jaxmps.scenes.hydrostatic(**overrides)
    except DOCUMENTED as e:
        # A scene too large for the limit names `spacing`, the setting to change.
        assert _names_a_parameter(str(e), [*overrides, "spacing"]), str(e)
        event("refused")
        return
    event("built")
    params = case.params
    jaxmps._params.check_values(params)  # finite, in range
    assert np.all(np.isfinite(np.asarray(case.state.position)))
    assert 0 < float(params.dt) < math.inf


def _stub_computation(monkeypatch):
    """run() as it is up to the first step, without computing: the command line's
    parsing, the scene, the output checks and the plan are the real ones."""
    monkeypatch.setattr(_driver, "_first_frame", lambda *args: {})
    monkeypatch.setattr(_driver, "_chunk", lambda c, o, state, *args: (state, {}))


TIMES = st.one_of(
    st.sampled_from(["nan", "inf", "-inf", "-1", "0", "1e400", "abc", "", "0.01"]),
    st.floats(allow_nan=True, allow_infinity=True).map(repr),
    st.floats(0.005, 0.1).map(repr),
)
SET_ITEMS = st.one_of(
    _settings(1).map(lambda d: [f"{k}={v}" for k, v in d.items()]),
    st.tuples(st.just("nonsense"), AWKWARD).map(lambda kv: [f"{kv[0]}={kv[1]}"]),
    st.sampled_from([["spacing"], ["=1"], ["spacing=="]]),
)
OUT_NAMES = st.one_of(
    st.just("run.h5"),
    st.sampled_from(["run.hdf5", "run.xdmf", "notes.txt", "folder", "a/b/run.h5", ""]),
)


@settings(
    max_examples=150,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(
    items=st.lists(SET_ITEMS, max_size=3).map(lambda x: sum(x, [])),
    t_end=st.none() | TIMES,
    save_every=st.none() | TIMES,
    out=OUT_NAMES,
)
# Found by the search: a save interval of 1e305 s (longer than any run) failed
# with "cannot convert float infinity to integer".
@example(items=[], t_end=None, save_every="1.8150185007695315e+305", out="run.h5")
def test_command_lines_run_or_fail_on_one_line(
    small_limit, monkeypatch, capsys, items, t_end, save_every, out
):
    _stub_computation(monkeypatch)
    folder = Path(tempfile.mkdtemp())
    (folder / "folder").mkdir()
    argv = ["run", "hydrostatic", "--quiet", "--out", str(folder / out)]
    for item in items:
        argv += ["--set", item]
    if t_end is not None:
        argv += ["--t-end", t_end]
    if save_every is not None:
        argv += ["--save-every", save_every]
    capsys.readouterr()
    try:
        code = main(argv)
    except SystemExit as e:
        code = e.code
    err = capsys.readouterr().err
    assert "Traceback" not in err
    event(f"exit code {code}")
    if code == 0:
        return
    assert code == 2, err
    lines = err.strip().splitlines()
    if lines[0].startswith("usage:"):  # argparse's own: usage, then one error line
        lines = lines[-1:]
    assert len(lines) == 1 and lines[0].startswith("jaxmps run: error: "), err
    named = ["--out", "--t-end", "--save-every", "--set", "t_end", "save_every"]
    names = [item.partition("=")[0] for item in items] + named + ["nonsense"]
    assert _names_a_parameter(lines[0], names), err


SWEPT = st.sampled_from(["density", "viscosity", "beta", "dt", "sound_speed"])
MEMBERS = st.lists(
    st.one_of(
        st.sampled_from([math.nan, math.inf, -math.inf, 0.0, -1000.0, 1e300]),
        st.floats(min_value=1e-7, max_value=1e-3),
        st.floats(min_value=1e-7, max_value=1e4),
    ),
    max_size=3,
)


@pytest.fixture(scope="module")
def small_case():
    return jaxmps.scenes.hydrostatic(spacing=0.05)


@settings(max_examples=200, deadline=None)
@given(values=st.dictionaries(SWEPT, MEMBERS, max_size=2))
def test_sweep_values_are_checked_per_member(small_case, values):
    try:
        batched, _, b = checked_batch(small_case, values)
    except DOCUMENTED as e:
        assert _names_a_parameter(str(e), values) or "Nothing to sweep" in str(e)
        event("refused")
        return
    event("accepted")
    assert b >= 1
    for name in values:
        value = np.asarray(getattr(batched, name))
        assert np.all(np.isfinite(value)) and np.all(value >= 0)


@settings(
    max_examples=10,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture],
)
@given(
    setting=st.sampled_from(["density", "viscosity", "gravity", "beta"]),
    scale=st.one_of(
        st.floats(0.5, 1.0),
        st.sampled_from([0.0, -1.0, math.nan, math.inf, 1e300]),
    ),
)
def test_a_few_real_runs_finish_finite_or_are_refused(small_case, setting, scale):
    """Two steps at the coarse spacing (one compiled program for all examples: dt
    is given, so every example has the same plan)."""
    dt = float(small_case.params.dt)
    value = DEFAULTS[setting] * scale  # half the time near the default
    try:
        case = jaxmps.scenes.hydrostatic(spacing=0.05, dt=dt, **{setting: value})
        result = jaxmps.run(case, t_end=2 * dt, save_every=dt, progress=False)
    except DOCUMENTED as e:
        assert setting in str(e), str(e)
        event("refused")
        return
    except RuntimeError as e:  # a run that failed says so, by its Result
        assert "failed between" in str(e)
        event("run failed")
        return
    event("ran")
    state = result.state
    active = np.asarray(state.active)
    assert np.all(np.isfinite(np.asarray(state.position)[active]))
    assert np.all(np.isfinite(np.asarray(state.pressure)[active]))
