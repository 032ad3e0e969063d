"""Run files: HDF5 round trip, XDMF sidecar, restart continuity, bad files."""

import xml.etree.ElementTree as ET

import h5py
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmps
from jaxmps import io


@pytest.fixture(scope="module")
def case():
    return jaxmps.scenes.hydrostatic(spacing=0.02)


@pytest.fixture(scope="module")
def rollout(case):
    return jaxmps.simulate(case.scene, case.params, case.state, 4, 2, throw=False)


def test_round_trip(tmp_path, case, rollout):
    probes = {"time": np.array([0.1, 0.2]), "level": np.array([1.0, 2.0])}
    path = io.write_run(tmp_path / "run.h5", case, rollout.saved, probes, rollout.state)
    with h5py.File(path) as f:
        assert f.attrs["format"] == "jaxmps-run"
        assert f.attrs["format_version"] == 1
        for key in ("jaxmps_version", "scene", "dim", "spacing", "dt"):
            assert key in f.attrs
        assert f["particles/kind"].dtype == np.int8
        assert f["particles/body"].dtype == np.int32
        assert np.all(f["particles/body"][...] == -1)
        assert f["frames/position"].maxshape[0] is None
        assert f["frames/active"].dtype == bool
    data = io.read_run(path)
    assert data.attrs["scene"] == "hydrostatic"
    assert data.config["spacing"] == 0.02
    assert data.config["dt"] == "adaptive"
    saved = rollout.saved
    for name in ("time", "position", "velocity", "pressure", "active"):
        np.testing.assert_array_equal(
            data.frames[name], np.asarray(getattr(saved, name))
        )
    np.testing.assert_array_equal(data.frames["step"], [2, 4])
    np.testing.assert_array_equal(data.probes["level"], probes["level"])
    np.testing.assert_array_equal(data.particles["kind"], np.asarray(case.state.kind))
    for name in ("time", "step", "position", "velocity", "pressure", "kind", "active"):
        np.testing.assert_array_equal(
            data.state[name], np.asarray(getattr(rollout.state, name))
        )
    assert int(data.state["result"]) == 0
    state = io.load_state(path, case)
    assert state.position.dtype == case.state.position.dtype
    np.testing.assert_array_equal(state.position, rollout.state.position)
    assert bool(state.result == jaxmps.Result.successful)


def test_append(tmp_path, case, rollout):
    with io.RunWriter(tmp_path / "run.h5", case) as w:
        w.append_frames(rollout.saved)
        w.append_frames(rollout.saved)
        w.append_probes({"time": np.zeros(2), "p": np.ones(2)})
        w.append_probes({"time": np.zeros(3), "p": np.ones(3)})
        w.write_state(rollout.state)
        w.write_state(rollout.state)
    data = io.read_run(tmp_path / "run.h5")
    assert data.frames["position"].shape == (4, *case.state.position.shape)
    assert data.probes["p"].shape == (5,)


def test_xdmf(tmp_path, case, rollout):
    io.write_run(tmp_path / "run.h5", case, rollout.saved)
    xdmf = tmp_path / "run.xdmf"
    assert xdmf.exists()
    root = ET.parse(xdmf).getroot()
    assert root.tag == "Xdmf"
    collection = root.find("Domain/Grid")
    assert collection.get("CollectionType") == "Temporal"
    grids = collection.findall("Grid")
    assert len(grids) == 2
    n, d = case.state.position.shape
    for grid in grids:
        assert grid.find("Topology").get("TopologyType") == "Polyvertex"
        assert grid.find("Topology").get("NumberOfElements") == str(n)
        assert grid.find("Geometry").get("GeometryType") == "XY"
        names = {a.get("Name") for a in grid.findall("Attribute")}
        assert {"Pressure", "Velocity"} <= names
    references = {e.text for e in root.iter("DataItem") if e.get("Format") == "HDF"}
    assert {
        "run.h5:/frames/position",
        "run.h5:/frames/pressure",
        "run.h5:/frames/velocity",
    } <= references
    with h5py.File(tmp_path / "run.h5") as f:
        for ref in references:
            assert ref.split(":", 1)[1] in f


def test_restart_continuity(tmp_path, case):
    dt = float(case.params.dt)
    n = 4
    whole = jaxmps.run(
        case,
        t_end=2 * n * dt,
        save_every=2 * dt,
        out=tmp_path / "a.h5",
        progress=False,
        chunk_saves=2,
    )
    jaxmps.run(
        case,
        t_end=n * dt,
        save_every=2 * dt,
        out=tmp_path / "b.h5",
        progress=False,
        chunk_saves=2,
    )
    rest = jaxmps.run(
        case,
        t_end=2 * n * dt,
        save_every=2 * dt,
        out=tmp_path / "b.h5",
        restart=True,
        progress=False,
        chunk_saves=2,
    )
    assert int(rest.state.step) == 2 * n == int(whole.state.step)
    # Bit for bit: the restored state is the full State, and the compiled step is
    # the same whatever the chunk length.
    for field in ("position", "velocity", "pressure"):
        np.testing.assert_array_equal(
            getattr(rest.state, field), getattr(whole.state, field)
        )
    a, b = io.read_run(tmp_path / "a.h5"), io.read_run(tmp_path / "b.h5")
    np.testing.assert_array_equal(a.frames["step"], b.frames["step"])
    np.testing.assert_array_equal(a.frames["position"], b.frames["position"])
    assert set(a.probes) == set(b.probes) >= {"time", "water_level"}
    assert len(b.probes["time"]) == len(b.frames["time"]) == n + 1
    np.testing.assert_allclose(whole.probes["time"], a.probes["time"])


def test_run_failure_writes_and_raises(tmp_path):
    # A far too large time step: the Courant check fails within a few steps.
    case = jaxmps.scenes.hydrostatic(spacing=0.02, dt=0.2)
    failure = r"failed between t=0 s and t=.*(candidate_capacity|Courant)"
    with pytest.raises(RuntimeError, match=failure):
        jaxmps.run(
            case,
            t_end=2.0,
            save_every=0.2,
            out=tmp_path / "f.h5",
            progress=False,
            chunk_saves=2,
        )
    data = io.read_run(tmp_path / "f.h5")
    assert len(data.frames["time"]) >= 2  # the initial frame and the failed save
    assert int(data.state["result"]) == 0


def test_random_bytes(tmp_path):
    path = tmp_path / "junk.h5"
    path.write_bytes(np.random.default_rng(0).bytes(4096))
    with pytest.raises(ValueError, match="junk.h5"):
        io.read_run(path)


def test_foreign_h5(tmp_path, case):
    path = tmp_path / "foreign.h5"
    with h5py.File(path, "w") as f:
        f["x"] = np.arange(3)
    with pytest.raises(ValueError, match=r"foreign\.h5.*format"):
        io.read_run(path)
    with pytest.raises(ValueError, match="foreign.h5"):
        io.load_state(path, case)


def test_wrong_case(tmp_path, case, rollout):
    path = io.write_run(tmp_path / "run.h5", case, rollout.saved, None, rollout.state)
    other = jaxmps.scenes.hydrostatic(spacing=0.025)
    with pytest.raises(ValueError, match="run.h5"):
        io.load_state(path, other)
    assert jnp.issubdtype(case.state.kind.dtype, jnp.integer)
