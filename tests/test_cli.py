"""The `jaxmps` command line: scenes, run, info, plot, and usage errors."""

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
