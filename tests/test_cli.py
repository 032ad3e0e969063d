"""The `jaxmps` command line: scenes, run, info, plot, and usage errors."""

import re

import jax.numpy as jnp
import numpy as np
import pytest

import jaxmps
from jaxmps.cli import main, parse_value


@pytest.fixture(scope="module")
def run_file(tmp_path_factory):
    out = tmp_path_factory.mktemp("cli") / "hydro.h5"
    code = main(
        [
            "run",
            "hydrostatic",
            "--set",
            "spacing=0.02",
            "--t-end",
            "0.01",
            "--out",
            str(out),
            "--quiet",
        ]
    )
    assert code == 0
    return out


def test_parse_value():
    assert parse_value("3") == 3 and isinstance(parse_value("3"), int)
    assert parse_value("0.02") == 0.02
    assert parse_value("1e-3") == 1e-3
    assert parse_value("None") is None
    assert parse_value("semi_implicit") == "semi_implicit"


def test_scenes(capsys):
    assert main(["scenes"]) == 0
    text = capsys.readouterr().out
    assert "dam_break" in text and "hydrostatic" in text
    assert "spacing" in text and "column_height" in text


def test_run_writes(run_file, capsys):
    assert run_file.exists()
    assert run_file.with_suffix(".xdmf").exists()
    data = jaxmps.io.read_run(run_file)
    assert data.attrs["scene"] == "hydrostatic"
    assert data.config["spacing"] == 0.02
    assert int(data.state["step"]) >= 1


def test_run_prints_where(tmp_path, capsys):
    out = tmp_path / "r.h5"
    main(
        [
            "run",
            "hydrostatic",
            "--set",
            "spacing=0.02",
            "--t-end",
            "0.004",
            "--out",
            str(out),
            "--quiet",
        ]
    )
    assert str(out) in capsys.readouterr().out


def test_unknown_parameter(tmp_path, capsys):
    with pytest.raises(SystemExit) as e:
        main(["run", "hydrostatic", "--set", "foo=1", "--out", str(tmp_path / "x.h5")])
    assert e.value.code == 2
    err = capsys.readouterr().err
    assert "foo" in err and "spacing" in err and "depth" in err
    assert "Traceback" not in err
    assert not (tmp_path / "x.h5").exists()


def test_unknown_scene(capsys):
    with pytest.raises(SystemExit) as e:
        main(["run", "no_such_scene"])
    assert e.value.code == 2
    assert "dam_break" in capsys.readouterr().err


def test_info(run_file, capsys):
    assert main(["info", str(run_file)]) == 0
    text = capsys.readouterr().out
    assert "hydrostatic" in text and "frames" in text and "water_level" in text


def test_info_counts_the_particles_not_the_free_slots(tmp_path, capsys):
    """A pool's free slots (inactive fluid slots, as inflows and grains keep) are
    not particles: `info` counts the active ones of the last state."""
    import dataclasses

    case = jaxmps.scenes.hydrostatic(spacing=0.05)
    fluid = np.asarray(case.state.kind) == int(jaxmps.Kind.FLUID)
    free = np.flatnonzero(fluid)[:3]
    active = np.asarray(case.state.active).copy()
    active[free] = False
    state = dataclasses.replace(case.state, active=jnp.asarray(active))
    path = tmp_path / "pool.h5"
    with jaxmps.io.RunWriter(path, case) as writer:
        writer.write_state(state)
    assert main(["info", str(path)]) == 0
    out = capsys.readouterr().out.splitlines()
    line = next(x for x in out if x.startswith("  particles"))
    n, n_fluid = len(active), int(fluid.sum())
    assert f"particles {n - 3} (fluid {n_fluid - 3}, " in line
    assert f"3 free slots of {n})" in line


def test_info_bad_file(tmp_path, capsys):
    bad = tmp_path / "bad.h5"
    bad.write_bytes(b"not an hdf5 file at all")
    with pytest.raises(SystemExit) as e:
        main(["info", str(bad)])
    assert e.value.code == 2
    assert "bad.h5" in capsys.readouterr().err


def test_plot(run_file, tmp_path):
    png = tmp_path / "snap.png"
    assert main(["plot", str(run_file), "--out", str(png)]) == 0
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    png2 = tmp_path / "first.png"
    assert main(["plot", str(run_file), "--time", "0", "--out", str(png2)]) == 0
    assert png2.exists()


def test_run_and_info_with_a_rigid_body(tmp_path, capsys):
    """A body scene runs from the command line; its file has /particles/body and a
    /bodies group, and `info` lists them."""
    out = tmp_path / "impact.h5"
    args = ["run", "block_impact", "--set", "spacing=0.25", "--t-end", "0.02"]
    assert main([*args, "--quiet", "--out", str(out)]) == 0
    data = jaxmps.io.read_run(out)
    assert set(np.unique(data.particles["body"])) == {-1, 0}
    assert data.bodies["centre"].shape[1:] == (1, 2)
    capsys.readouterr()
    assert main(["info", str(out)]) == 0
    assert "bodies   1 rigid" in capsys.readouterr().out


# ------------------------------------------------------------ one line, exit 2


def _one_line_error(capsys, argv, code=2):
    with pytest.raises(SystemExit) as exit_:
        main(argv)
    assert exit_.value.code == code
    err = capsys.readouterr().err
    assert "Traceback" not in err and len(err.strip().splitlines()) == 1, err
    return err


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--t-end", "nan"], "--t-end must be positive and finite"),
        (["--t-end", "-1"], "--t-end must be positive and finite"),
        (["--save-every", "0"], "--save-every must be positive and finite"),
        (["--set", "gravity=nan"], "gravity must be finite and >= 0"),
        (["--set", "courant=0"], r"courant must be finite, in \(0, 1\]"),
        (
            ["--set", "gravity=0"],
            r"gravity=0(\.0)? leaves no velocity scale.*give `dt_max`",
        ),
        (["--set", "spacing=1e-5"], r"asks for 4e\+08 particles.*raise `spacing`"),
        (["--set", "spacing"], "--set expects NAME=VALUE"),
        (["--set", "dim=2.5"], "expects a whole number"),
        (["--max-steps-per-save", "-5"], "--max-steps-per-save must be at least 1"),
    ],
)
def test_run_refuses_on_one_line(tmp_path, capsys, argv, message):
    out = tmp_path / "r.h5"
    err = _one_line_error(capsys, ["run", "hydrostatic", *argv, "--out", str(out)])
    assert err.startswith("jaxmps run: error: ")
    assert re.search(message, err), err
    assert list(tmp_path.iterdir()) == []


def test_info_and_plot_of_bad_files(tmp_path, run_file, capsys):
    err = _one_line_error(capsys, ["info", str(tmp_path / "missing.h5")])
    assert err.startswith("jaxmps info: error: ") and "missing.h5" in err
    text = tmp_path / "notanh5.txt"
    text.write_text("hello")
    err = _one_line_error(capsys, ["info", str(text)])
    assert "notanh5.txt" in err and "not HDF5" in err
    corrupt = tmp_path / "corrupt.h5"
    corrupt.write_bytes(run_file.read_bytes()[:3000])
    err = _one_line_error(capsys, ["plot", str(corrupt)])
    assert err.startswith("jaxmps plot: error: ") and "corrupt.h5" in err
    err = _one_line_error(capsys, ["plot", str(run_file), "--time", "5"])
    assert "--time 5.0 lies outside the run's frames, t = 0 ..." in err
    png = tmp_path / "folder.png"
    png.mkdir()
    err = _one_line_error(capsys, ["plot", str(run_file), "--out", str(png)])
    assert "is a directory" in err
    sweep = tmp_path / "a_sweep"
    sweep.mkdir()
    err = _one_line_error(capsys, ["plot", str(sweep)])
    assert "is a sweep's folder (or index), not a run file" in err
    # A folder that does not exist yet is made, as `run` makes its --out's.
    deep = tmp_path / "new" / "frame.png"
    assert main(["plot", str(run_file), "--out", str(deep)]) == 0 and deep.exists()


def test_a_platform_jax_cannot_start_is_one_line(tmp_path):
    """JAX_PLATFORMS naming a platform the machine lacks (here a made-up one; cuda
    on a machine without a GPU fails the same way)."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    env = {
        **os.environ,
        "PYTHONPATH": str(Path(__file__).resolve().parents[1]),
        "JAX_PLATFORMS": "no_such_platform",
    }
    out = tmp_path / "r.h5"
    command = [sys.executable, "-m", "jaxmps.cli", "run", "hydrostatic"]
    done = subprocess.run(
        [*command, "--out", str(out)],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 2, done.stderr
    assert done.stderr.startswith("jaxmps run: error: JAX cannot start its backend")
    assert "JAX_PLATFORMS=no_such_platform" in done.stderr
    assert "Traceback" not in done.stderr and not out.exists()


def test_an_internal_error_is_one_line_unless_debug(monkeypatch, capsys):
    def broken():
        raise KeyError("a bug")

    monkeypatch.setattr(jaxmps.scenes, "available", broken)
    err = _one_line_error(capsys, ["scenes"], code=1)
    assert err.startswith("jaxmps scenes: internal error, please report it")
    assert "--debug" in err and "KeyError" in err
    with pytest.raises(KeyError, match="a bug"):
        main(["scenes", "--debug"])
    with pytest.raises(KeyError, match="a bug"):
        main(["--debug", "scenes"])


def test_info_of_a_run_file_missing_a_dataset(tmp_path, run_file, capsys):
    import shutil

    import h5py

    damaged = tmp_path / "damaged.h5"
    shutil.copy(run_file, damaged)
    with h5py.File(damaged, "r+") as f:
        del f["particles/kind"]
    err = _one_line_error(capsys, ["info", str(damaged)])
    assert err.startswith("jaxmps info: error: ") and "damaged run file" in err
