"""The flume's groundsill geometry (seed 002 §3, §6): crest, step, apron, reach,
blocks in their recess, a fixed-bed scour hole, the transition to the lowered
bed; and the flow over the step's brink."""

import numpy as np
import pytest

import jaxmps
from jaxmps import Kind
from jaxmps.scenes._flume_bed import bed_profile

# A groundsill with every piece, at l0 = 2.5 mm: crest 5 cm, step 1 cm, apron
# 10 cm, 4 rows of 1.75 x 1.25 cm blocks 2.5 mm apart, a scour hole 20 cm long
# and 5 cm deep exposing 1 cm of the last block, a 1 : 10 transition by 2 cm.
SILL = dict(
    spacing=0.0025,
    discharge=0.006,
    inflow_depth=0.015,
    crest_length=0.05,
    step_height=0.01,
    apron_length=0.1,
    reach_length=0.4,
    block_rows=4,
    block_length=0.0175,
    block_height=0.0125,
    block_gap=0.0025,
    scour_length=0.2,
    scour_depth=0.05,
    scour_exposure=0.01,
    transition_length=0.2,
    bed_lowering=0.02,
    bed_length=0.9,
)


def _profile(case):
    c = case.config
    layers = jaxmps.geometry.layers_for(case.scene.r_e / c["spacing"])
    return bed_profile(c, c["bed_length"], -(layers + 1) * c["spacing"])


def test_profile_has_the_pieces_where_the_settings_put_them():
    case = jaxmps.scenes.flume(**SILL)
    profile = _profile(case)
    h = profile.height
    assert h(0.025) == 0.0  # crest
    assert h(0.1) == pytest.approx(-0.01)  # apron, a step below
    assert profile.apron_end == pytest.approx(0.15)
    assert h(0.2) == pytest.approx(-0.0225)  # recess under the blocks
    assert profile.protection_end == pytest.approx(0.15 + 4 * 0.02)
    hole = 0.23 + 0.1  # the deepest point, the hole's middle
    assert h(hole) == pytest.approx(-0.01 - 0.05)
    assert h(0.23 + 1e-6) == pytest.approx(-0.02, abs=1e-5)  # exposure 1 cm
    assert h(0.5) == pytest.approx(-0.01)  # reach, back at the apron's level
    assert h(0.65) == pytest.approx(-0.02)  # halfway down the transition
    assert h(0.8) == pytest.approx(-0.03)  # lowered bed: Delta H = 2 cm
    # the hollows filled to their brims (where still water would stand)
    filled = profile.filled(np.array([0.2, hole, 0.65, 0.8]))
    np.testing.assert_allclose(filled, [-0.01, -0.01, -0.02, -0.03], atol=1e-12)


def test_bed_is_lined_with_walls_and_the_water_and_blocks_lie_on_it():
    """Every lattice point within l0 under the bed's surface is a pressure wall,
    those behind it dummies to the boundary's depth; the walls on the apron,
    in the recess and on the 1 : 10 transition have the flat bed's number
    density (0.676 n0 from walls and dummies at r_e = 2.1 l0; on the transition
    in the mean); no fluid lies
    under the surface; the blocks fill the recess to the apron's level."""
    case = jaxmps.scenes.flume(**SILL)
    profile, l0 = _profile(case), SILL["spacing"]
    x, kind = np.asarray(case.state.position), np.asarray(case.state.kind)
    active = np.asarray(case.state.active)
    bed = active & ((kind == int(Kind.WALL)) | (kind == int(Kind.DUMMY)))
    bed &= x[:, 0] > 0  # not the inflow's columns
    depth = profile.distance(x)
    under = x[:, 1] < profile.height(x[:, 0])
    wall = bed & (kind == int(Kind.WALL))
    assert np.all(under[bed])
    assert np.all(depth[wall] < l0)
    assert np.all(depth[bed & ~wall] >= l0)
    assert depth[bed].max() < 3 * l0
    fluid = active & (kind == int(Kind.FLUID))
    assert not np.any(under[fluid])
    solids = x[active & ((kind == int(Kind.WALL)) | (kind == int(Kind.DUMMY)))]
    r_e = case.scene.r_e

    def density(points):
        d = np.linalg.norm(points[:, None] - solids[None], axis=-1)
        near = (d > 0) & (d < r_e)
        return np.where(near, r_e / np.where(near, d, 1.0) - 1.0, 0.0).sum(1)

    n = density(x[wall]) / case.scene.n0
    xw = x[wall]
    regions = {
        "apron": (xw[:, 0] > 0.06) & (xw[:, 0] < 0.14),
        "recess": (xw[:, 0] > 0.16) & (xw[:, 0] < 0.22) & (xw[:, 1] < -0.02),
        "transition": (xw[:, 0] > 0.56) & (xw[:, 0] < 0.74),
    }
    for name, where in regions.items():
        assert where.sum() > 5, name
    for name in ("apron", "recess"):
        np.testing.assert_allclose(n[regions[name]], 0.676, atol=0.005, err_msg=name)
    # The transition is a staircase of one-cell steps: 0.5 n0 at a step's
    # outer corner, 0.75 at its inner one, the flat bed's between (mean 0.667).
    slope = n[regions["transition"]]
    assert slope.mean() == pytest.approx(0.676, rel=0.02)
    assert slope.min() > 0.49 and slope.max() < 0.76
    rigid = x[kind == int(Kind.RIGID)]
    assert len(rigid) == 4 * 7 * 5
    assert rigid[:, 1].max() == pytest.approx(-0.01 - 0.5 * l0)
    assert rigid[:, 1].min() == pytest.approx(-0.0225 + 0.5 * l0)
    assert int(case.scene.rigid.count) == 4


def test_flat_flume_is_the_default():
    """Without a crest the bed is one flat crest: a wall row at -l0/2 and
    dummies under it, the water h_in deep moving at q / h_in."""
    case = jaxmps.scenes.flume(spacing=0.0075, bed_length=0.3)
    x, kind = np.asarray(case.state.position), np.asarray(case.state.kind)
    wall = (kind == int(Kind.WALL)) & (x[:, 0] > 0)
    assert np.allclose(x[wall, 1], -0.00375)
    fluid = np.asarray(case.state.active) & (kind == int(Kind.FLUID))
    assert x[fluid, 1].max() < case.config["inflow_depth"]
    u = np.asarray(case.state.velocity)[fluid, 0]
    assert np.allclose(u, 0.04 / case.config["inflow_depth"])


def test_tail_depth_fills_behind_the_weir_with_the_discharge():
    case = jaxmps.scenes.flume(
        spacing=0.005,
        crest_length=0.1,
        step_height=0.1,
        bed_length=0.6,
        weir_height=0.08,
        tail_depth=0.15,
    )
    x, kind = np.asarray(case.state.position), np.asarray(case.state.kind)
    fluid = np.asarray(case.state.active) & (kind == int(Kind.FLUID))
    below = fluid & (x[:, 0] > 0.3)
    assert x[below, 1].max() == pytest.approx(-0.1 + 0.15 - 0.0025)
    u = np.asarray(case.state.velocity)[below, 0]
    assert np.allclose(u, 0.04 / 0.15)


@pytest.mark.parametrize(
    "settings, match",
    [
        (dict(crest_length=0.5, apron_length=0.4, reach_length=0.2), "bed_length"),
        (dict(step_height=0.02), "crest_length"),
        (
            dict(crest_length=0.1, reach_length=0.05, block_rows=3),
            "reach_length",
        ),
        (
            dict(
                crest_length=0.1,
                reach_length=0.3,
                scour_length=0.1,
                scour_depth=0.01,
                scour_exposure=0.02,
            ),
            "scour_exposure",
        ),
        (
            dict(
                crest_length=0.1,
                reach_length=0.3,
                scour_length=0.1,
                scour_depth=0.02,
                scour_centre=0.2,
            ),
            "scour_centre",
        ),
        (dict(block_rows=-1), "block_rows"),
        (dict(bed_lowering=-0.01), "bed_lowering"),
    ],
)
def test_groundsill_settings_that_do_not_fit_are_refused(settings, match):
    with pytest.raises(ValueError, match=match):
        jaxmps.scenes.flume(spacing=0.01, bed_length=1.0, **settings)


@pytest.mark.long
def test_brink_depth_of_the_free_overfall():
    """Water entering at the critical depth h_c = (q^2 / g)^(1/3) on a crest
    leaves it over a free overfall (the step) at the brink depth 0.715 h_c
    (Rouse 1936; 0.70-0.72 in experiments). Semi-implicit MPS, q = 0.012
    m^2/s, l0 = 2.5 mm (10 layers), a 20 cm crest and a 5 cm step; the depth
    is the water's volume in the last 2 l0 of the crest, averaged over
    0.6-1.5 s. Measured 0.744 h_c (float32) and 0.777 h_c (float64; the
    explicit solver 0.777), +4 to +9 %: the strip's centre lies l0 upstream
    of the brink, where the surface still falls steeply, and the surface
    fluctuates by 0.07 h_c between frames. Upstream it stands 1.1-1.2 h_c
    deep, subcritical as it must be."""
    l0, q = 0.0025, 0.012
    h_c = (q * q / 9.81) ** (1 / 3)
    case = jaxmps.scenes.flume(
        spacing=l0,
        discharge=q,
        inflow_depth=h_c,
        crest_length=0.2,
        step_height=0.05,
        bed_length=0.3,
        t_end=1.5,
    )
    times = np.linspace(0.025, 1.5, 60)
    out = jaxmps.simulate(case.scene, case.params, case.state, times=times)
    x = np.asarray(out.saved.position)
    fluid = np.asarray(out.saved.active) & (
        np.asarray(case.state.kind)[None] == int(Kind.FLUID)
    )
    late = np.asarray(out.saved.time) > 0.6

    def depth(a, b):
        strip = fluid & (x[..., 0] > a) & (x[..., 0] < b)
        return float(strip.sum(axis=1)[late].mean() * l0 * l0 / (b - a))

    brink = depth(0.2 - 2 * l0, 0.2)
    assert brink / h_c == pytest.approx(0.715, rel=0.1)
    upstream = depth(0.05, 0.1)
    assert 1.0 < upstream / h_c < 1.3


def _block_motion(case, out) -> tuple[float, float]:
    """The largest displacement of a block's centre [m] and tilt [degrees]."""
    rigid = out.saved.bodies
    moved = np.asarray(rigid["centre"]) - np.asarray(case.state.rigid.centre)[None]
    tilt = np.degrees(np.abs(np.asarray(rigid["orientation"])))
    return float(np.abs(moved).max()), float(tilt.max())


@pytest.mark.parametrize(
    "solver", ["semi_implicit", pytest.param("explicit", marks=pytest.mark.slow)]
)
def test_blocks_rest_in_their_recess_in_still_water(solver):
    """Four rows in the recess, the last one's face against the lip of a scour
    hole, in still water (q -> 0): the bed carries them, none moves by 0.05 l0
    or tilts by 0.5 degrees (which moves a corner by 0.05 l0) in 0.05 s (a
    free fall would take it 12 mm; measured at most 0.15 degrees). The
    contact push once took the recess's concave corners, the walls next to
    them (their normals tilted by the corner) and the hole's lip for overlaps
    of 0.1-0.3 l0: the walls pushed a block with 65-330 N/m (semi-implicit) or
    4600 N/m (explicit, whose dt is 10 x smaller and the push's stiffness
    100 x larger) against its 4.9 N/m weight and threw the last one out,
    spinning 300 degrees in 0.05 s."""
    case = jaxmps.scenes.flume(**{**SILL, "discharge": 1e-6, "solver": solver})
    times = np.linspace(0.005, 0.05, 10)
    out = jaxmps.simulate(case.scene, case.params, case.state, times=times)
    moved, tilt = _block_motion(case, out)
    assert moved < 0.05 * SILL["spacing"]
    assert tilt < 0.5


@pytest.mark.long
def test_blocks_hold_in_the_flow_over_them():
    """Seed 002's Case 3-2 protection (no washout at q = 0.006 m^2/s with 0.8
    cm of the last block's face exposed): here 1 cm of the 1.25 cm face exposed
    to a scour hole 5 cm deep, the explicit E-MPS of the seed (c = 10 m/s),
    mu = 0.6, 0.5 s of the flow starting over them: no block moves by 0.1 l0 or
    tilts by 0.5 degrees (measured 0.00 mm over 1 s, float32). Before the
    water between the blocks started still, it was squeezed into their faces
    in the first step (it moved at q / depth) and threw the last block out."""
    case = jaxmps.scenes.flume(**{**SILL, "solver": "explicit", "sound_speed": 10.0})
    times = np.linspace(0.05, 0.5, 10)
    out = jaxmps.simulate(case.scene, case.params, case.state, times=times)
    moved, tilt = _block_motion(case, out)
    assert moved < 0.1 * SILL["spacing"]
    assert tilt < 0.5
    # the water does run over them (q / h_in = 0.4 m/s where it enters)
    x, u = np.asarray(out.saved.position[-1]), np.asarray(out.saved.velocity[-1])
    fluid = np.asarray(out.saved.active[-1]) & (
        np.asarray(case.state.kind) == int(Kind.FLUID)
    )
    over = fluid & (x[:, 0] > 0.15) & (x[:, 0] < 0.23) & (x[:, 1] > -0.01)
    assert over.sum() > 20
    assert u[over, 0].mean() > 0.2
