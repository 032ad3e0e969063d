"""Sweeps over several devices and processes: the same values as on one device,
bit for bit in float64; the `jaxmps sweep` command and its index; two processes
joined by `jax.distributed`; and what bad input gets. Several CPU devices need
XLA_FLAGS before JAX starts, so these run in subprocesses."""

import json
import os
import socket
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from helpers import python_with_devices

import jaxmps
from jaxmps.cli import main

ROOT = Path(__file__).resolve().parents[1]


def _python(code: str, devices: int = 1, timeout: float = 300, env=None):
    """Run `code` in a fresh interpreter with `devices` CPU devices; its stdout."""
    return python_with_devices(code, devices, timeout, env)


@pytest.mark.slow
def test_sweep_over_four_devices_equals_one_device():
    """Five members (padded to two per device) and four members (one per device)
    split over four CPU devices give the bits of the one-device sweep."""
    out = _python(
        """
        import json, jax, numpy as np, jaxmps
        from jaxmps import member_mesh
        assert jax.device_count() == 4 and jax.config.jax_enable_x64
        case = jaxmps.scenes.dam_break(spacing=0.02)
        report = {}
        for count in (5, 4):
            values = {"viscosity": np.linspace(1e-6, 5e-6, count)}
            runs = {
                d: jaxmps.sweep(case, values, times=[0.02, 0.04],
                                mesh=member_mesh(devices=d))
                for d in (1, 4)
            }
            same = jax.tree.map(np.array_equal, runs[1].saved, runs[4].saved)
            moved = float(np.ptp(runs[1].saved["front"][:, -1]))
            report[count] = {
                "same": all(jax.tree.leaves(same)),
                "results": np.asarray(runs[4].result).tolist(),
                "spread": moved,
            }
        print(json.dumps(report))
        """,
        devices=4,
    )
    report = json.loads(out.strip().splitlines()[-1])
    for count, row in report.items():
        assert row["same"], count
        assert row["results"] == [0] * int(count)
    # The members differ (otherwise equality would say little): the
    # viscosity spread moves the surge front.
    assert report["5"]["spread"] > 0


def test_member_mesh_refuses_what_does_not_exist():
    _python(
        """
        import jax, numpy as np, pytest, jaxmps
        from jax.sharding import Mesh
        from jaxmps import member_mesh
        with pytest.raises(ValueError, match="devices=8 asked for, but 2 CPU"):
            member_mesh(devices=8)
        with pytest.raises(ValueError, match="one axis"):
            member_mesh(Mesh(np.asarray(jax.devices()).reshape(1, 2), ("a", "b")))
        with pytest.raises(ValueError, match="whole number"):
            member_mesh(devices=1.5)
        case = jaxmps.scenes.hydrostatic(spacing=0.05)
        with pytest.raises(ValueError, match="at least one member"):
            jaxmps.sweep(case, {"viscosity": []}, n_steps=2)
        """,
        devices=2,
    )


def test_sweep_command_writes_a_run_file_per_member_and_an_index(tmp_path, capsys):
    out = tmp_path / "sw"
    argv = ["sweep", "hydrostatic", "--vary", "viscosity=1e-6,2e-6"]
    argv += ["--vary", "density=1000,1200", "--set", "spacing=0.04"]
    argv += ["--t-end", "0.02", "--save-every", "0.01", "--out", str(out), "--quiet"]
    main(argv)
    index = json.loads((out / "sweep.json").read_text())
    assert index["format"] == "jaxmps-sweep" and index["varied"] == [
        "viscosity",
        "density",
    ]
    members = index["members"]
    assert [m["values"] for m in members] == [
        {"viscosity": 1e-6, "density": 1000.0},
        {"viscosity": 1e-6, "density": 1200.0},
        {"viscosity": 2e-6, "density": 1000.0},
        {"viscosity": 2e-6, "density": 1200.0},
    ]
    assert all(m["result"] == "successful" for m in members)
    assert all(m["t_reached"] == pytest.approx(0.02) for m in members)
    for m in members:
        data = jaxmps.io.read_run(out / m["file"])
        np.testing.assert_allclose(data.frames["time"], [0.0, 0.01, 0.02])
        assert data.config["density"] == m["values"]["density"]
        assert json.loads(data.attrs["sweep_values"]) == m["values"]
    # The heavier member presses harder on the bottom.
    bottom = [
        jaxmps.io.read_run(out / m["file"]).probes["pressure_bottom"][-1]
        for m in members[:2]
    ]
    assert bottom[1] / bottom[0] == pytest.approx(1.2, rel=0.02)
    capsys.readouterr()
    main(["info", str(out)])
    shown = capsys.readouterr().out
    assert "4 members, 4 successful" in shown
    assert "member_003.h5  viscosity=2e-06, density=1200  successful" in shown
    # An existing sweep is not overwritten without --overwrite.
    with pytest.raises(SystemExit) as e:
        main(argv)
    assert e.value.code == 2
    assert "not empty" in capsys.readouterr().err


@pytest.mark.parametrize(
    "argv, message",
    [
        (["--vary", "viscosity"], "--vary expects NAME=V1,V2"),
        (["--vary", "viscosity=1e-6,thick"], "values must be numbers"),
        (["--vary", "viscosty=1e-6"], "Unknown Params field 'viscosty'"),
        (["--vary", "viscosity=1e-6", "--devices", "9"], "devices=9 asked for"),
        (["--vary", "viscosity=-1"], "viscosity"),
        (["--vary", "viscosity=1e-6", "--out", "x.h5"], "names a run file"),
        (["--vary", "viscosity=1e-6", "--num-processes", "2"], "go together"),
        (["--vary", "gravity=9.81,5"], "--vary gravity: Params.gravity is a vector"),
    ],
)
def test_sweep_command_refuses_bad_input(tmp_path, capsys, monkeypatch, argv, message):
    monkeypatch.chdir(tmp_path)
    base = ["sweep", "hydrostatic", "--set", "spacing=0.05", "--t-end", "0.01"]
    with pytest.raises(SystemExit) as e:
        main(base + argv)
    assert e.value.code == 2
    assert message in capsys.readouterr().err
    assert not any(tmp_path.iterdir())  # nothing written


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("localhost", 0))
        return s.getsockname()[1]


def _sweep_process(out: Path, extra: list[str], devices: int = 1, t_end="0.02"):
    env = {
        **os.environ,
        "XLA_FLAGS": f"--xla_force_host_platform_device_count={devices}",
        "JAX_PLATFORMS": "cpu",
        "PYTHONPATH": str(ROOT),
    }
    argv = [sys.executable, "-m", "jaxmps.cli", "sweep", "hydrostatic"]
    argv += ["--vary", "viscosity=1e-6,2e-6,3e-6", "--set", "spacing=0.04"]
    argv += ["--t-end", t_end, "--save-every", "0.01", "--quiet", "--x64"]
    argv += ["--out", str(out)] + extra
    return subprocess.Popen(
        argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env
    )


@pytest.mark.slow
def test_two_processes_run_one_sweep(tmp_path):
    """Two processes on this machine (a localhost coordinator, CPU collectives by
    Gloo), one device each: process 0 writes the files, with the values of the
    same sweep in one process."""
    port = _free_port()
    joint = tmp_path / "joint"
    procs = [
        _sweep_process(
            joint,
            ["--coordinator", f"localhost:{port}", "--num-processes", "2"]
            + ["--process-id", str(i), "--timeout", "60"],
        )
        for i in range(2)
    ]
    outputs = [p.communicate(timeout=300) for p in procs]
    for p, (stdout, stderr) in zip(procs, outputs):
        assert p.returncode == 0, stderr[-3000:]
    assert "in 2 process(es)" in outputs[0][0]
    alone = tmp_path / "alone"
    single = _sweep_process(alone, [])
    _, stderr = single.communicate(timeout=300)
    assert single.returncode == 0, stderr[-3000:]
    index = json.loads((joint / "sweep.json").read_text())
    assert index["processes"] == 2 and index["devices"] == 2
    for m in index["members"]:
        a = jaxmps.io.read_run(joint / m["file"]).frames
        b = jaxmps.io.read_run(alone / m["file"]).frames
        for name in ("position", "velocity", "pressure"):
            np.testing.assert_array_equal(a[name], b[name])


def test_a_coordinator_that_never_answers_ends_in_a_bounded_wait(tmp_path):
    port = _free_port()  # nothing listens there
    proc = _sweep_process(
        tmp_path / "never",
        ["--coordinator", f"localhost:{port}", "--num-processes", "2"]
        + ["--process-id", "1", "--timeout", "3"],
    )
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 2
    assert "could not join the run at --coordinator" in stderr
    assert "--timeout 3 s" in stderr


def test_one_run_split_over_devices_equals_one_device():
    """A dam break whose particle arrays are split over four devices (XLA
    partitions the program) ends where the one-device run ends, to round-off;
    a capacity the device count does not divide is refused. (The pressure solves
    converge to round-off, so that only the two programs are compared.)"""
    out = _python(
        """
        import json, jax, numpy as np, pytest, jaxmps
        case = None
        for k in range(200):
            trial = jaxmps.scenes.dam_break(
                spacing=0.02 * (1 - 0.001 * k), dt=1e-3, rtol=1e-13
            )
            if trial.scene.capacity % 4 == 0:
                case = trial
                break
        odd = jaxmps.scenes.dam_break(spacing=0.02)
        if odd.scene.capacity % 4:
            with pytest.raises(ValueError, match="not a multiple of the 4 devices"):
                jaxmps.shard_particles(odd.state, devices=4)
        split = jaxmps.shard_particles(case.state, devices=4)
        assert len(split.position.sharding.device_set) == 4
        runs = [
            jaxmps.simulate(case.scene, case.params, s, 40, 20)
            for s in (case.state, split)
        ]
        moved = float(np.max(np.abs(runs[0].state.position - case.state.position)))
        diff = float(np.max(np.abs(runs[0].state.position - runs[1].state.position)))
        print(json.dumps({"moved": moved, "diff": diff}))
        """,
        devices=4,
    )
    report = json.loads(out.strip().splitlines()[-1])
    assert report["moved"] > 0.01  # the column has collapsed by a centimetre
    assert report["diff"] < 1e-12


@pytest.mark.long
def test_calibrating_a_batch_over_two_devices_equals_one_device():
    """Two dam breaks under different gravity share one viscosity: over two
    devices (one member each) the batched fit is the one-device fit to 1e-12;
    its loss is the mean of the two single-curve losses and its plain gradient
    step the mean of theirs (1e-6: the batch decides neighbour-list reuse
    jointly)."""
    out = _python(
        """
        import json, numpy as np, optax, jaxmps
        from jaxmps import member_mesh
        from jaxmps.calibration import Curve, Identity
        case = jaxmps.scenes.dam_break(spacing=0.0146, dt=1e-3)
        g = (9.81, 5.0)
        gravity = np.array([[0.0, -x] for x in g])
        t = np.linspace(0.005, 0.02, 4)
        curves = [Curve(times=t, values=0.15 + 0.5 * k * t) for k in range(2)]
        common = dict(optimiser=optax.sgd(1e-9), iterations=2,
                      initial={"viscosity": 1e-5}, progress=False)
        fields = {"viscosity": Identity()}
        histories = [
            jaxmps.calibrate(case, fields, curves, "front", 20, 5,
                             batch={"gravity": gravity},
                             mesh=member_mesh(devices=d), **common).history
            for d in (1, 2)
        ]
        singles = [
            jaxmps.calibrate(jaxmps.scenes.dam_break(spacing=0.0146, dt=1e-3,
                                                     gravity=x),
                             fields, curves[k], "front", 20, 5, **common).history
            for k, x in enumerate(g)
        ]
        print(json.dumps([histories, singles]))
        """,
        devices=2,
    )
    (one, two), singles = json.loads(out.strip().splitlines()[-1])
    assert one["loss"][0] > 0
    np.testing.assert_allclose(two["loss"], one["loss"], rtol=1e-12)
    np.testing.assert_allclose(two["viscosity"], one["viscosity"], rtol=1e-12)
    mean_loss = np.mean([h["loss"][0] for h in singles])
    assert one["loss"][0] == pytest.approx(mean_loss, rel=1e-6)
    steps = [h["viscosity"][1] - h["viscosity"][0] for h in singles]
    assert abs(np.mean(steps)) > 0  # the step moved the viscosity
    step = one["viscosity"][1] - one["viscosity"][0]
    assert step == pytest.approx(np.mean(steps), rel=1e-6)


def test_a_sweep_result_saves_to_one_file(tmp_path):
    import h5py

    case = jaxmps.scenes.hydrostatic(spacing=0.05)
    values = {"viscosity": np.array([1e-6, 2e-6, 3e-6])}
    res = jaxmps.sweep(case, values, times=[0.01, 0.02])
    res.save(tmp_path / "sweep.h5")
    with h5py.File(tmp_path / "sweep.h5") as f:
        np.testing.assert_array_equal(f["values/viscosity"][...], values["viscosity"])
        for name, value in res.saved.items():
            np.testing.assert_array_equal(f[f"saved/{name}"][...], value)
        assert f["saved/time"].shape == (3, 2)
        assert json.loads(f.attrs["messages"]) == ["successful"] * 3


def test_a_sweep_stopped_by_sigint_keeps_its_chunks(tmp_path):
    """SIGINT during a sweep of many chunks: the chunk being computed is written,
    the sweep stops there (exit 130) and the index says how far each member got,
    which its run file holds."""
    import signal
    import time

    folder = tmp_path / "stopped"
    proc = _sweep_process(folder, [], t_end="5.0")  # 500 saves, 25 chunks
    deadline = time.monotonic() + 120
    while not (folder / "sweep.json").exists() and time.monotonic() < deadline:
        time.sleep(0.02)
    proc.send_signal(signal.SIGINT)
    _, stderr = proc.communicate(timeout=120)
    assert proc.returncode == 130, stderr[-2000:]
    assert "stopped by SIGINT" in stderr
    members = json.loads((folder / "sweep.json").read_text())["members"]
    for m in members:
        assert 0 < m["t_reached"] < 5.0
        data = jaxmps.io.read_run(folder / m["file"])
        assert data.frames["time"][-1] == pytest.approx(m["t_reached"])
        assert data.state["time"] == pytest.approx(m["t_reached"])
