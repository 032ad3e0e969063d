"""Run files are never lost or clobbered: refused input touches no file, a new file
appears only with its first frame, and whatever stops a run (an exception, a full
disk, SIGINT, SIGTERM) leaves a readable file with every frame written so far and
the state to restart from."""

import errno
import json
import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import jax
import numpy as np
import pytest

import jaxmps
from jaxmps import _driver, io
from jaxmps.cli import main

REPOSITORY = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def case():
    return jaxmps.scenes.hydrostatic(spacing=0.05)


def _run(case, path, **kwargs):
    dt = float(case.params.dt)
    kwargs = {"t_end": 8 * dt, "save_every": 2 * dt, "chunk_saves": 2, **kwargs}
    return jaxmps.run(case, out=path, progress=False, **kwargs)


def _snapshot(path: Path):
    return path.read_bytes(), path.stat().st_mtime_ns


def _leftovers(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir() if p.name.endswith(".partial"))


def test_an_existing_file_is_refused_without_overwrite(tmp_path, case, capsys):
    path = tmp_path / "keep.h5"
    _run(case, path)
    before = _snapshot(path)
    with pytest.raises(ValueError, match=r"keep\.h5.*exists.*overwrite"):
        _run(case, path)
    args = ["run", "hydrostatic", "--set", "spacing=0.05", "--out", str(path)]
    with pytest.raises(SystemExit) as exit_:
        main([*args, "--quiet"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert err.startswith("jaxmps run: error: --out") and "--overwrite" in err
    assert "Traceback" not in err
    assert _snapshot(path) == before


def test_a_refused_setting_leaves_the_file_alone(tmp_path, case, capsys):
    """Even with --overwrite: settings are checked before any file is touched."""
    path = tmp_path / "keep.h5"
    _run(case, path)
    before = _snapshot(path)
    # A fixed step beyond the viscous limit (adaptive steps would bound it).
    args = ["run", "hydrostatic", "--set", "spacing=0.05", "--set", "viscosity=1.0"]
    args += ["--set", "dt=0.001"]
    with pytest.raises(SystemExit) as exit_:
        main([*args, "--out", str(path), "--overwrite", "--quiet"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err.strip()
    assert err.startswith("jaxmps run: error:") and "viscosity=1" in err
    assert "\n" not in err
    viscous = jaxmps.scenes.hydrostatic(spacing=0.05, viscosity=1.0, dt=0.001)
    with pytest.raises(ValueError, match="viscous stability limit"):
        _run(viscous, path, overwrite=True)
    assert _snapshot(path) == before
    assert len(io.read_run(path).frames["time"]) == 5
    assert _leftovers(tmp_path) == []


def test_overwrite_replaces_the_file(tmp_path, case):
    path = tmp_path / "run.h5"
    _run(case, path)
    dt = float(case.params.dt)
    _run(case, path, t_end=4 * dt, overwrite=True)
    assert list(io.read_run(path).frames["step"]) == [0, 2, 4]
    assert _leftovers(tmp_path) == []


@pytest.mark.parametrize(
    "name, message",
    [
        ("run.xdmf", r"--out '.*run\.xdmf' must end in \.h5 or \.hdf5"),
        ("notes.txt", r"--out '.*notes\.txt' must end in \.h5 or \.hdf5"),
        ("folder.h5", r"--out '.*folder\.h5' is a directory"),
        ("a_file/run.h5", r"--out '.*a_file/run\.h5': '.*a_file' is not a directory"),
        ("fresh.h5", r"--out '.*fresh\.h5': '.*fresh\.xdmf' exists"),
    ],
)
def test_output_names_that_must_not_be_written(tmp_path, capsys, name, message):
    (tmp_path / "run.h5").write_bytes(b"the run the sidecar describes")
    (tmp_path / "notes.xdmf").write_text("unrelated")
    (tmp_path / "notes.txt").write_text("unrelated")
    (tmp_path / "fresh.xdmf").write_text("unrelated")
    (tmp_path / "folder.h5").mkdir()
    (tmp_path / "a_file").write_text("unrelated")
    before = {p.name: p.stat().st_mtime_ns for p in tmp_path.iterdir()}
    with pytest.raises(SystemExit) as exit_:
        main(["run", "hydrostatic", "--out", str(tmp_path / name), "--quiet"])
    assert exit_.value.code == 2
    err = capsys.readouterr().err
    assert len(err.strip().splitlines()) == 1
    assert re.search(message, err), err
    assert {p.name: p.stat().st_mtime_ns for p in tmp_path.iterdir()} == before


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes to read-only folders")
def test_a_read_only_folder_is_refused_up_front(tmp_path, case):
    folder = tmp_path / "read_only"
    folder.mkdir()
    folder.chmod(0o555)
    try:
        with pytest.raises(ValueError, match=r"out '.*run\.h5'.*not writable"):
            _run(case, folder / "run.h5")
    finally:
        folder.chmod(0o755)


def test_an_exception_mid_run_keeps_the_frames_written(tmp_path, case, monkeypatch):
    calls = []
    simulate = _driver.simulate

    def failing(*args, **kwargs):
        calls.append(1)
        if len(calls) == 2:
            raise MemoryError("out of device memory")
        return simulate(*args, **kwargs)

    monkeypatch.setattr(_driver, "simulate", failing)
    path = tmp_path / "run.h5"
    with pytest.raises(MemoryError):
        _run(case, path)
    data = io.read_run(path)
    # The first frame and the first chunk of two saves; /state at its end.
    np.testing.assert_array_equal(data.frames["step"], [0, 2, 4])
    assert int(data.state["step"]) == 4 and int(data.state["result"]) == 0
    np.testing.assert_array_equal(data.state["position"], data.frames["position"][-1])
    assert path.with_suffix(".xdmf").exists()
    assert _leftovers(tmp_path) == []
    # An exception that is not the run's own failure leaves it 'running': it
    # stopped without finishing, and a restart continues it.
    assert data.attrs["status"] == "running"


def test_the_file_says_how_the_run_ended(tmp_path, case, capsys):
    dt = float(case.params.dt)
    path = tmp_path / "run.h5"
    _run(case, path)
    data = io.read_run(path)
    assert data.attrs["status"] == "complete" and data.attrs["status_message"] == ""
    assert data.attrs["t_end"] == 8 * dt and data.attrs["save_every"] == 2 * dt
    assert main(["info", str(path)]) == 0
    assert "run      complete (asked for t_end" in capsys.readouterr().out
    # A file at its end continues only to a later one.
    with pytest.raises(ValueError, match=r"already at t=.*give a later t_end"):
        _run(case, path, restart=True, t_end=None)
    # A step 40 times the largest fails at its first save: the file says so.
    failing = jaxmps.scenes.hydrostatic(spacing=0.05, dt=40 * dt)
    bad = tmp_path / "failed.h5"
    with pytest.raises(RuntimeError, match="failed between"):
        _run(failing, bad, t_end=320 * dt, save_every=80 * dt)
    data = io.read_run(bad)
    assert data.attrs["status"] == "failed"
    assert "failed between" in data.attrs["status_message"]
    assert int(data.state["result"]) == 0  # /state: the last good save's
    main(["info", str(bad)])
    assert "run      failed" in capsys.readouterr().out


def _disk_full_after(monkeypatch, calls: int):
    append = io.RunWriter.append_frames
    count = []

    def append_frames(self, *args, **kwargs):
        count.append(1)
        if len(count) > calls:
            raise OSError(errno.ENOSPC, "No space left on device")
        return append(self, *args, **kwargs)

    monkeypatch.setattr(io.RunWriter, "append_frames", append_frames)


def test_a_full_disk_keeps_what_was_written(tmp_path, case, monkeypatch):
    _disk_full_after(monkeypatch, 2)
    path = tmp_path / "run.h5"
    with pytest.raises(OSError, match=r"run\.h5.*No space left.*restart") as error:
        _run(case, path)
    assert error.value.errno == errno.ENOSPC
    data = io.read_run(path)
    np.testing.assert_array_equal(data.frames["step"], [0, 2, 4])
    assert int(data.state["step"]) == 4
    assert _leftovers(tmp_path) == []


def test_a_full_disk_before_the_first_frame_keeps_the_old_file(
    tmp_path, case, monkeypatch
):
    path = tmp_path / "run.h5"
    _run(case, path)
    before = _snapshot(path)
    _disk_full_after(monkeypatch, 0)
    with pytest.raises(OSError, match="No space left"):
        _run(case, path, overwrite=True)
    assert _snapshot(path) == before
    assert _leftovers(tmp_path) == []


@pytest.mark.parametrize("signum", [signal.SIGINT, signal.SIGTERM])
def test_a_signal_stops_the_run_with_a_valid_file(tmp_path, signum):
    """A run in its own process, signalled once its file exists (after the first
    frame): it writes the chunk being computed, exits with 128 + the signal, and
    leaves every frame and the state of the last one."""
    path = tmp_path / "run.h5"
    command = [sys.executable, "-m", "jaxmps.cli", "run", "hydrostatic"]
    command += ["--set", "spacing=0.05", "--t-end", "1000", "--save-every", "0.01"]
    command += ["--out", str(path), "--quiet"]
    env = {**os.environ, "PYTHONPATH": str(REPOSITORY), "JAX_PLATFORMS": "cpu"}
    process = subprocess.Popen(
        command, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True
    )
    try:
        deadline = time.monotonic() + 120
        while not path.exists() and process.poll() is None:
            assert time.monotonic() < deadline, "no run file after 120 s"
            time.sleep(0.1)
        assert process.poll() is None, process.communicate()
        process.send_signal(signum)
        _, err = process.communicate(timeout=120)
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()
    assert process.returncode == 128 + signum, err
    assert f"stopped by {signal.Signals(signum).name}" in err
    assert f"--restart {path}" in err and "Traceback" not in err
    data = io.read_run(path)
    steps = data.frames["step"]
    # At least the first frame (the signal may come before the first chunk).
    assert len(steps) >= 1 and steps[0] == 0 and np.all(np.diff(steps) > 0)
    assert int(data.state["step"]) == steps[-1]
    assert int(data.state["result"]) == 0
    assert len(data.probes["time"]) == len(steps)
    assert _leftovers(tmp_path) == []
    assert data.attrs["status"] == "interrupted"
    assert data.attrs["t_end"] == 1000 and data.attrs["save_every"] == 0.01
    assert f"stopped by {signal.Signals(signum).name}" in data.attrs["status_message"]


def test_a_restart_continues_to_the_end_the_file_was_asked_for(tmp_path, case):
    """As after a signal: a file stopped short of its t_end. A restart without
    one goes on to it, on the same grid of saves."""
    dt = float(case.params.dt)
    path = tmp_path / "run.h5"
    _run(case, path, t_end=4 * dt)
    with io.RunWriter(path, case, append=True) as writer:
        writer.record_run(8 * dt, 2 * dt)  # as if asked for 8 steps
    result = jaxmps.run(case, out=path, restart=True, progress=False, chunk_saves=2)
    assert int(result.state.step) == 8
    data = io.read_run(path)
    np.testing.assert_array_equal(data.frames["step"], [0, 2, 4, 6, 8])
    assert data.attrs["status"] == "complete"


def test_a_restart_of_another_scene_is_refused(tmp_path, case, capsys):
    path = tmp_path / "run.h5"
    _run(case, path)
    before = _snapshot(path)
    with pytest.raises(SystemExit) as exit_code:
        main(["run", "dam_break", "--restart", str(path)])
    assert exit_code.value.code == 2
    err = capsys.readouterr().err
    assert "is a run of 'hydrostatic', not 'dam_break'" in err
    assert _snapshot(path) == before


def test_a_restart_in_another_precision_is_refused(tmp_path):
    path = tmp_path / "run.h5"
    with jax.enable_x64(True):
        case = jaxmps.scenes.hydrostatic(spacing=0.05)
        _run(case, path)
    before = _snapshot(path)
    with jax.enable_x64(False):
        single = jaxmps.scenes.hydrostatic(spacing=0.05)
        assert single.state.position.dtype == np.float32
        with pytest.raises(ValueError, match=r"float64 run.*continue it with --x64"):
            _run(single, path, restart=True)
    assert _snapshot(path) == before


def test_the_run_ends_at_t_end(tmp_path, case):
    dt = float(case.params.dt)  # still water: every step is the largest
    # Four saves of 2 steps (two chunks of two), then a last save of 1 step.
    result = _run(case, None, t_end=9 * dt)
    assert int(result.state.step) == 9
    assert float(result.state.time) == 9 * dt
    np.testing.assert_allclose(
        result.probes["time"] / dt, [0, 2, 4, 6, 8, 9], rtol=1e-12
    )
    # A run shorter than one step is one shorter step.
    short = _run(case, None, t_end=0.5 * dt)
    assert int(short.state.step) == 1 and float(short.state.time) == 0.5 * dt
    with pytest.raises(ValueError, match=r"t_end=1e\+300 s is .* steps .* beyond"):
        _run(case, None, t_end=1e300, save_every=1e-300)
    for bad in (float("nan"), float("inf"), -1.0, 0.0):
        with pytest.raises(ValueError, match=r"t_end must be positive and finite"):
            _run(case, None, t_end=bad)
        with pytest.raises(ValueError, match=r"save_every must be positive"):
            _run(case, None, save_every=bad)


def test_saves_closer_than_a_fixed_step_are_warned_of(tmp_path):
    fixed = jaxmps.scenes.hydrostatic(spacing=0.05, dt=1e-3)
    assert fixed.scene.time_step is None
    with pytest.warns(UserWarning, match=r"save_every=0.0005 s is shorter than the"):
        result = jaxmps.run(fixed, t_end=2e-3, save_every=5e-4, progress=False)
    assert int(result.state.step) == 4  # steps of the save interval, not of dt


def test_a_restart_with_other_settings_keeps_the_ones_it_replaced(tmp_path, case):
    dt = float(case.params.dt)
    path = tmp_path / "run.h5"
    _run(case, path, t_end=4 * dt)
    thicker = jaxmps.scenes.hydrostatic(spacing=0.05, viscosity=1e-4)
    _run(thicker, path, t_end=8 * dt, restart=True)
    data = io.read_run(path)
    assert data.config["viscosity"] == 1e-4
    earlier = json.loads(data.attrs["earlier_configs"])
    assert len(earlier) == 1 and earlier[0]["config"]["viscosity"] == 1e-6
    assert earlier[0]["until_time"] == pytest.approx(4 * dt)
    # A restart with the same settings adds nothing.
    _run(thicker, path, t_end=10 * dt, restart=True)
    assert len(json.loads(io.read_run(path).attrs["earlier_configs"])) == 1
