"""Porous regions with a porosity: the weight that makes water stand sparser in
them, the porosity field, the thinning of a case's water, still water in a
region (its share, its pressure, the level a gauge reads), water filling a porous
bed to the level volume conservation gives, and what bad input gets."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import jaxmps
from jaxmps import Kind, PorousRegion, fluid, scenes
from jaxmps._coupling import Coupling
from jaxmps._step import _coupling, _merged_apart
from jaxmps.fluid import FreeSurface
from jaxmps.operators import make_pairs

# A region through the whole depth of a 0.4 m x 0.2 m tank, over x = 0.1-0.3 m.
_BOX = "0.1,-1,0.3,1"


def _region(phi, **kwargs):
    return dict(
        porous_kappa=0.05,
        porous_box=kwargs.pop("box", _BOX),
        porous_direction="all",
        porous_porosity=phi,
        **kwargs,
    )


def _porous_bed(phi, spacing, **settings):
    """A 0.3 m x 0.2 m column at the left of a 0.6 m tank whose right half is a
    porous region of porosity `phi` over a wet bed (`bed_depth` in `settings`)."""
    return scenes.dam_break(
        column_width=0.3,
        column_height=0.2,
        tank_length=0.6,
        tank_height=0.35,
        spacing=spacing,
        **settings,
        **_region(phi, box="0.3,-1,2,2"),
    )


def _stretched_density(disc, phi, weight):
    """Brute force: the number density of the centre of a square/cubic lattice of
    spacing l0 phi^(-1/d), each neighbour weighing `weight`."""
    spacing = disc.spacing * phi ** (-1.0 / disc.dim)
    reach = int(np.ceil(disc.r_e / spacing)) + 1
    axes = [np.arange(-reach, reach + 1) * spacing] * disc.dim
    points = np.stack(np.meshgrid(*axes), -1).reshape(-1, disc.dim)
    r = np.linalg.norm(points, axis=1)
    r = r[(r > 0) & (r < disc.r_e)]
    return weight * float(np.sum(np.asarray(disc.weight.value(r, disc.r_e))))


@pytest.mark.parametrize(
    "scheme, dim", [("standard", 2), ("standard", 3), ("high_accuracy", 2)]
)
def test_pore_weight_makes_the_stretched_lattice_read_n0(scheme, dim):
    """A lattice stretched to hold phi of the water, its pairs weighing the pore
    weight, has the number density n0, at the table's nodes to round-off and
    between them to 1 %; the weight is 1 at phi = 1 and grows as phi falls."""
    disc = scenes.hydrostatic(spacing=0.02, scheme=scheme, dim=dim).scene.discretisation
    regions = fluid.PorousRegions(
        lower=((0.0,) * dim,),
        upper=((1.0,) * dim,),
        axes=(None,),
        porosity=(0.85,),
        transition=0.04,
        weight_table=fluid.pore_weights(disc),
    )
    nodes, _ = regions.weight_table
    lowest = fluid.lowest_porosity(disc)
    assert nodes[0] == lowest and nodes[-1] == 1.0
    for phi in (nodes[0], nodes[20], 1.0):
        weight = float(fluid.pore_weight(regions, jnp.asarray([phi]))[0])
        assert _stretched_density(disc, phi, weight) == pytest.approx(disc.n0, 1e-12)
    between = 0.5 * (nodes[7] + nodes[8])
    weight = float(fluid.pore_weight(regions, jnp.asarray([between]))[0])
    assert _stretched_density(disc, between, weight) == pytest.approx(disc.n0, 0.01)
    weights = np.asarray(fluid.pore_weight(regions, jnp.asarray(nodes)))
    assert weights[-1] == 1.0 and np.all(np.diff(weights) < 0)


def test_porosity_field_passes_smoothly_across_the_box_faces():
    """phi(x) is 1 beyond the transition outside the box, the porosity beyond it
    inside, monotone between, and centred on the face: the water it removes
    across a face is (1 - phi) times the distance inside, as for a sharp box."""
    width, phi = 0.02, 0.7
    regions = fluid.PorousRegions(
        lower=((0.3, -1.0),),
        upper=((0.6, 1.0),),
        axes=(None,),
        porosity=(phi,),
        transition=width,
        weight_table=((phi, 1.0), (2.0, 1.0)),
    )
    x = np.linspace(0.2, 0.45, 2501)
    position = jnp.asarray(np.stack([x, np.zeros_like(x)], 1))
    field = np.asarray(fluid.porosity_field(regions, jnp.zeros(2), position))
    assert np.all(field[x < 0.3 - width / 2] == 1.0)
    assert np.allclose(field[x > 0.3 + width / 2], phi, atol=1e-15)
    assert np.all(np.diff(field) <= 0)
    removed = np.trapezoid(1 - field, x)
    assert removed == pytest.approx((1 - phi) * (0.45 - 0.3), rel=1e-6)


def test_fill_pores_keeps_phi_of_the_water_evenly_and_only_in_regions():
    """The built-in scenes thin a region's water to phi: in the core phi of the
    sites stay (within 0.02), as evenly in every 5 x 5 window (within 0.15), none
    outside the transition goes; the rest are pool slots parked at the origin; a
    region of porosity 1 changes nothing and compiles no porosity."""
    plain = scenes.hydrostatic(width=0.4, depth=0.2, spacing=0.01)
    case = scenes.hydrostatic(width=0.4, depth=0.2, spacing=0.01, **_region(0.85))
    x = np.asarray(plain.state.position)
    water = np.asarray(plain.state.kind) == int(Kind.FLUID)
    kept = np.asarray(case.state.active)
    core = water & (x[:, 0] > 0.11) & (x[:, 0] < 0.29)
    assert kept[core].mean() == pytest.approx(0.85, abs=0.02)
    for x0 in np.arange(0.11, 0.25, 0.05):
        for y0 in np.arange(0.0, 0.15, 0.05):
            window = core & (x[:, 0] >= x0) & (x[:, 0] < x0 + 0.05)
            window &= (x[:, 1] >= y0) & (x[:, 1] < y0 + 0.05)
            assert kept[window].mean() == pytest.approx(0.85, abs=0.15)
    far = water & ((x[:, 0] < 0.09) | (x[:, 0] > 0.31))
    assert kept[far].all() and kept[~water].all()
    gone = ~kept & np.asarray(plain.state.active)
    origin = np.asarray(case.scene.grid.origin)
    assert np.all(np.asarray(case.state.position)[gone] == origin)
    again = scenes.hydrostatic(width=0.4, depth=0.2, spacing=0.01, **_region(0.85))
    assert np.array_equal(np.asarray(again.state.active), kept)
    full = scenes.hydrostatic(width=0.4, depth=0.2, spacing=0.01, **_region(1.0))
    assert full.scene.porous.porosity is None
    assert np.array_equal(np.asarray(full.state.active), np.asarray(plain.state.active))
    assert _coupling(full.scene, full.params, full.state) is None
    assert _coupling(case.scene, case.params, case.state).pores is not None


def test_still_water_in_a_porous_region_holds_phi_at_open_water_pressure():
    """Still water with a region of phi = 0.85 through its depth (l0 = 1 cm, saves
    over 0.5-1.5 s): the region's core holds 0.85 of the water (within 0.05), the
    mean pressure along its floor is the open water's (within 2 %; measured
    +0.4 to +1.0 % at phi = 0.7-0.95), its free surface (the highest particle
    of each column of l0) stands at the open water's (within l0/2), and a level
    gauge over it, which counts a particle there as 1/phi of its volume, reads
    the open water's level (counted from the open water's particles) within l0:
    it reads the region's share of water over phi (measured +0.6 l0 here, where
    the core holds 0.87; counted as water it would read 2.6 l0 low)."""
    l0 = 0.01
    case = scenes.hydrostatic(
        width=0.4, depth=0.2, spacing=l0, dt=0.1 * l0, **_region(0.85)
    )
    traj = jaxmps.simulate(
        case.scene, case.params, case.state, times=np.linspace(0.5, 1.5, 11)
    )
    assert traj.result == jaxmps.Result.successful
    water = np.asarray(case.state.kind) == int(Kind.FLUID)
    core_p, open_p, shares = [], [], []
    for k in range(11):
        live = np.asarray(traj.saved.active[k]) & water
        x = np.asarray(traj.saved.position[k])
        p = np.asarray(traj.saved.pressure[k])
        core = live & (x[:, 0] > 0.13) & (x[:, 0] < 0.27)
        open_ = live & ((x[:, 0] < 0.07) | (x[:, 0] > 0.33))
        floor = x[:, 1] < 2 * l0
        core_p.append(p[core & floor].mean())
        open_p.append(p[open_ & floor].mean())
        shares.append(np.sum(core & (x[:, 1] < 0.15)) * l0**2 / (0.14 * 0.15))
    assert np.mean(core_p) == pytest.approx(np.mean(open_p), rel=0.02)
    assert np.mean(shares) == pytest.approx(0.85, abs=0.05)
    gauge = scenes.StripLevel("over_region", 0.2, 0.1, l0, 0.0, softness=1.0)
    x = np.asarray(traj.state.position)
    live = np.asarray(traj.state.active) & water
    open_level = np.sum(live & (x[:, 0] > 0.32)) * l0**2 / 0.08
    assert abs(float(gauge(case.scene, traj.state)) - open_level) < l0

    def surface(lower, upper):
        tops = []
        for left in np.arange(lower, upper, l0):
            column = live & (x[:, 0] >= left) & (x[:, 0] < left + l0)
            if column.any():
                tops.append(x[column, 1].max())
        return np.mean(tops)

    assert abs(surface(0.13, 0.27) - surface(0.32, 0.4)) < 0.5 * l0


def test_water_filling_a_porous_bed_rises_to_the_level_its_pores_give():
    """A 0.3 m x 0.2 m column flows into the porous right half of a 0.6 m tank
    (phi = 0.85, a 3 cm wet bed thinned to it, l0 = 1 cm). At rest the open
    water's level is V / (0.3 (1 + phi)) (V = 0.06 + 0.009 phi m^2), 0.69 l0 above
    the level without porosity: within 0.35 l0 of it at 2.5-3 s, and more than
    0.35 l0 above the level without porosity (measured at phi = 0.7-0.9: -0.12
    to -0.30 l0 from it)."""
    l0, phi = 0.01, 0.85
    case = _porous_bed(phi, l0, bed_depth=0.03)
    traj = jaxmps.simulate(
        case.scene, case.params, case.state, times=np.linspace(2.5, 3.0, 6)
    )
    assert traj.result == jaxmps.Result.successful
    water = np.asarray(case.state.kind) == int(Kind.FLUID)
    levels = []
    for k in range(6):
        live = np.asarray(traj.saved.active[k]) & water
        x = np.asarray(traj.saved.position[k])
        levels.append(np.sum(live & (x[:, 0] < 0.2)) * l0**2 / 0.2)
    level = float(np.mean(levels))
    analytic = (0.06 + 0.009 * phi) / (0.3 * (1 + phi))
    assert abs(level - analytic) < 0.35 * l0
    assert level - 0.069 / 0.6 > 0.35 * l0


@pytest.mark.parametrize(
    "settings, message",
    [
        (_region(0.0), "porous_porosity"),
        (_region(-0.5), "porous_porosity"),
        (_region(1.5), "porous_porosity"),
        (_region(float("nan")), "porous_porosity"),
        (_region(0.7), "porous_porosity=0.7 is below 0.81"),
        (_region(0.9, solver="explicit"), "needs the semi-implicit solver"),
        (dict(porous_porosity=0.9), "need a region"),
    ],
)
def test_bad_porosity_is_refused_naming_the_setting(settings, message):
    with pytest.raises(ValueError, match=message):
        scenes.hydrostatic(width=0.4, depth=0.2, spacing=0.02, **settings)


def test_porosity_in_region_lists_and_run_file_config():
    """A region's porosity comes through `porous_regions` (objects and dicts) and
    its dict form, so that a run file rebuilds the same scene."""
    region = PorousRegion(box=((0.1, -1.0), (0.3, 1.0)), kappa=0.05, porosity=0.9)
    assert PorousRegion.of(region.as_dict()).as_dict() == region.as_dict()
    for listed in ([region], [region.as_dict()]):
        case = scenes.hydrostatic(
            width=0.4, depth=0.2, spacing=0.02, porous_regions=listed
        )
        assert case.scene.porous.porosity == (0.9,)
        assert case.config["porous_regions"][0]["porosity"] == 0.9


def test_isolated_surface_filter_counts_a_sparse_neighbour_as_the_water_it_stands_for():
    """In a region at phi = 0.8 an interior particle has 8 neighbours, fewer than
    the filter's 10: counted one by one, a dip of its number density below
    beta n0 left it flagged (P = 0) and the pressure around it fell for a step.
    Counted by the pore weight it stands for, it is un-flagged like a dip in open
    water; a particle on the block's top row stays surface either way."""
    disc = scenes.hydrostatic(spacing=0.01).scene.discretisation
    phi = 0.8
    spacing = disc.spacing * phi ** (-0.5)
    grid = np.stack(np.meshgrid(np.arange(11), np.arange(11)), -1).reshape(-1, 2)
    position = jnp.asarray(grid * spacing)
    n = position.shape[0]
    index = np.tile(np.arange(n), (n, 1))
    index = jnp.asarray(np.where(index == np.arange(n)[:, None], n, index))
    pairs = make_pairs(index, position, disc.weight, disc.r_e)
    regions = fluid.PorousRegions(
        lower=((-1.0, -1.0),),
        upper=((1.0, 1.0),),
        axes=(None,),
        porosity=(phi,),
        transition=0.02,
        weight_table=fluid.pore_weights(disc),
    )
    pore = fluid.pore_weight(regions, jnp.full((n,), phi))
    kind = jnp.full((n,), int(Kind.FLUID))
    active = jnp.ones((n,), bool)
    centre, top = 60, 115
    density = jnp.full((n,), disc.n0).at[centre].set(0.9 * disc.n0)
    density = density.at[top].set(0.5 * disc.n0)
    assert int(jnp.sum(pairs.valid[centre])) == 8
    args = (FreeSurface(), jnp.asarray(0.97), disc.n0, density, kind, active, pairs)
    one_by_one = np.asarray(fluid.detect_surface(*args))
    weighted = np.asarray(fluid.detect_surface(*args, pore))
    assert one_by_one[centre] and not weighted[centre]
    assert one_by_one[top] and weighted[top]


def test_merged_coupling_keeps_each_models_wall_contact_marks():
    """`Coupling.apart` (a body making its own wall contact) survives the merge
    of several models' couplings, whichever sets it."""
    n = 4
    base = dict(
        density=jnp.full((n,), 1000.0),
        owner=jnp.full((n,), -1),
        as_fluid=jnp.zeros((n,), bool),
    )
    marked = Coupling(**base, apart=jnp.asarray([1, 0, 2, 0]))
    other = Coupling(**base, apart=jnp.asarray([0, 1, 0, 0]))
    plain = Coupling(**base)
    assert np.array_equal(_merged_apart(marked, plain), [1, 0, 2, 0])
    assert np.array_equal(_merged_apart(plain, marked), [1, 0, 2, 0])
    assert np.array_equal(_merged_apart(marked, other), [1, 1, 2, 0])
    assert _merged_apart(plain, plain) is None


@pytest.mark.slow
def test_kappa_gradient_through_a_porous_bed_matches_finite_differences():
    """d(loss)/d log kappa of water flowing into a porous bed (phi = 0.85, 60
    steps, float64) by reverse mode against central differences: the porosity's
    weights, smooth in the positions, keep the rollout differentiable
    (measured 7e-5 relative at h = 1e-4)."""
    import equinox as eqx

    case = _porous_bed(0.85, 0.02, bed_depth=0.04, dt=2e-3)
    observe = scenes.observe_probes(case.probes)

    def loss(log_kappa):
        kappa = jnp.exp(log_kappa)[None]
        params = eqx.tree_at(lambda p: p.porous.kappa, case.params, kappa)
        traj = jaxmps.simulate(
            case.scene, params, case.state, n_steps=60, save_every=10, observe=observe
        )
        return jnp.sum(traj.saved["front"] ** 2) + jnp.sum(
            traj.saved["gauge_depth"] ** 2
        )

    x = jnp.log(0.05)
    grad = float(jax.grad(loss)(x))
    h = 1e-4
    fd = float((loss(x + h) - loss(x - h)) / (2 * h))
    assert abs(grad - fd) <= 1e-3 * abs(fd)
    assert abs(fd) > 0
