"""Bed-protection blocks below a groundsill on a fixed, scoured bed: seed 002's
washout cases (Ch. 5) and its fixed-bed failure limit (Method A, §8.2)."""

import dataclasses

import equinox as eqx
import jax.numpy as jnp

from .._params import Params
from ._case import Case
from ._common import resolve, setting_length
from ._flume import DEFAULTS as _FLUME
from ._flume import flume
from ._flume_bed import optional

# Seed 002's two measured scour holes below the blocks (discharge 0.006 m^2/s):
# bed lowering Delta H [m] -> (hole length L, deepest point Z_d, exposure of the
# last block's downstream face Z_b) [m]. Case 3-2 at 5 min (no washout) and Case
# 3-3 at 54 s (one second before its last row washed out).
MEASURED_HOLES = {
    0.02: (0.19, 0.064, 0.008),
    0.04: (0.10, 0.050, 0.013),
}

# The experiment's block: 1.9 x 1.3 cm across the flume's 2.5 cm, 2300 kg/m^3.
_BLOCK_MASS_PER_WIDTH = 2300.0 * 0.019 * 0.013  # kg per m of width

BLOCK_WASHOUT = {
    **{k: v for k, v in _FLUME.items() if k not in ("dim", "spacing", "t_end")},
    "discharge": 0.006,
    "inflow_depth": None,  # None: the critical depth (q^2 / g)^(1/3)
    "bed_length": 2.0,
    # seed 002 Case 3-x: main body 6.5 cm, apron 30 cm; the drop is in a
    # figure only: 2 cm (Case 2-x's).
    "crest_length": 0.065,
    "step_height": 0.02,
    "apron_length": 0.30,
    "transition_length": 0.5,
    "bed_lowering": 0.02,
    "reach_length": None,  # None: the blocks and the hole
    "scour_length": None,  # None: the hole model (`scour_hole`)
    "scour_depth": None,
    "scour_exposure": None,
    # seed 002 Ch. 5 and §8.2 at l0 = 2.5 mm: 16 rows of 1.75 x 1.25 cm blocks
    # 0.25 cm apart; None: the density that keeps the experiment's block mass.
    "block_rows": 16,
    "block_length": 0.0175,
    "block_height": 0.0125,
    "block_gap": 0.0025,
    "block_density": None,
    "mu_static": 0.6,
    "release_time": 60.0,
    "solver": "explicit",
    "sound_speed": 10.0,
    "wall_pressure": "facing",
    "spacing": 0.0025,
    "dim": 2,
    "t_end": 180.0,
}


def scour_hole(bed_lowering: float) -> tuple[float, float, float]:
    """The fixed-bed scour hole (length L, deepest point Z_d, exposure Z_b of the
    last block's face) [m] for a bed lowering Delta H [m]: linear in Delta H
    between seed 002's two holes measured below blocks (`MEASURED_HOLES`: Delta H
    = 2 cm, L 19 cm, Z_d 6.4 cm, Z_b 0.8 cm; Delta H = 4 cm, L 10 cm, Z_d 5 cm,
    Z_b 1.3 cm), held at the nearer one outside that range.

    Seed 002's own shape model (its Table 8.2, fitted to holes without blocks
    as well) is in figures only; this one uses only the holes measured with the
    blocks in place, and so takes no account of the discharge."""
    (low, a), (high, b) = sorted(MEASURED_HOLES.items())
    w = min(max((bed_lowering - low) / (high - low), 0.0), 1.0)
    return tuple(float((1 - w) * x + w * y) for x, y in zip(a, b))


def block_washout(**overrides) -> Case:
    """Seed 002's fixed-bed washout (Ch. 5, §8.2 Method A): a groundsill (crest
    `crest_length`, a drop of `step_height`, an apron of `apron_length`), rows
    of bed-protection blocks below it, a scour hole in the fixed bed below the
    last row, a transition of `transition_length` falling by `bed_lowering`
    (Delta H) and a free overfall at `bed_length`, fed at `discharge` q over the
    crest at the critical depth; explicit E-MPS with the wall pressure copied
    from the facing fluid, as the seed. Its defaults are the seed's (l0 = 2.5
    mm, 16 rows of 1.75 x 1.25 cm blocks 2.5 mm apart, mu = 0.6, a 60 s
    spin-up with the blocks held, then 120 s).

    The hole (`scour_length`, `scour_depth`, `scour_exposure`) follows Delta H
    by `scour_hole` unless given: with Delta H = 2 cm it is Case 3-2's (0.8 cm
    of the last block's face exposed; no block washed out in the experiment),
    with 4 cm Case 3-3's (the whole face exposed; the last row washed out, then
    rows 1-4 within 8 s). The blocks' density defaults to the one that keeps
    the experiment's block mass (14.2 g over 2.5 cm of width) at their size on
    the lattice (2597 kg/m^3 at the default size), as the seed.

    Seed 002's failure criterion is the washout of the last row: the probe
    `blocks_out` counts the blocks that have left their place; `block{k}_x`
    etc. are the flume's (k = 0 beside the apron, the last row k = rows - 1).
    Everything else is `flume`'s (`jaxmps.scenes.flume`). `Params.inflow.depth`
    is set to the depth fed, so that a batch of discharges (`critical_feed`) runs as one
    sweep on the case built for the largest.
    """
    c = resolve("block_washout", BLOCK_WASHOUT, overrides)
    if int(c["dim"]) != 2:
        raise ValueError("block_washout is 2-D only for now (dim=2).")
    hole = scour_hole(float(c["bed_lowering"]))
    for key, value in zip(("scour_length", "scour_depth", "scour_exposure"), hole):
        if c[key] is None:
            c[key] = value
    c["scour_exposure"] = min(c["scour_exposure"], c["block_height"])
    if c["inflow_depth"] is None:
        c["inflow_depth"] = (c["discharge"] ** 2 / c["gravity"]) ** (1 / 3)
    l0 = c["spacing"]
    length, height = (
        setting_length(c, "block_length"),
        setting_length(c, "block_height"),
    )
    if c["block_density"] is None:
        c["block_density"] = _BLOCK_MASS_PER_WIDTH / (length * height)
    if c["reach_length"] is None:
        # the gap and the hole as `flume` builds them (whole spacings, a gap
        # at least one where there is one), so that they fit at any spacing
        gap = optional(c["block_gap"], l0)
        protection = int(c["block_rows"]) * (length + gap)
        c["reach_length"] = protection + optional(c["scour_length"], l0)
    case = flume(**c)
    params = fed_depth(case)
    return Case(
        "block_washout",
        case.scene,
        params,
        case.state,
        case.probes,
        case.t_end,
        {**case.config, "block_density": c["block_density"], "hole": hole},
    )


def fed_depth(case: Case) -> Params:
    """The case's Params with `inflow.depth` the depth its inflow feeds (the
    layer's full height), so that a sweep can feed less: a batch of discharges
    (`critical_feed`) as one run on the case built for the largest."""
    inflow = case.params.inflow
    depth = jnp.asarray(case.config["inflow_depth"], inflow.velocity.dtype)
    return eqx.tree_at(
        lambda p: p.inflow, case.params, dataclasses.replace(inflow, depth=depth)
    )


def critical_feed(case: Case, discharge: float) -> tuple[float, float]:
    """The (`inflow.velocity`, `inflow.depth`) that feed `discharge` [m^2/s] at
    its critical depth through `case`'s inflow (built for a discharge at least
    as large): whole rows of the lattice, at the speed that carries `discharge`
    through them."""
    l0, g = case.config["spacing"], case.config["gravity"]
    rows = max(1, round((discharge**2 / g) ** (1 / 3) / l0))
    if rows * l0 > case.config["inflow_depth"] + 1e-12:
        raise ValueError(
            f"discharge={discharge:g} m^2/s needs {rows} rows of inflow but the case "
            f"feeds {case.config['inflow_depth']:g} m; build it for the largest "
            "discharge."
        )
    return discharge / (rows * l0), rows * l0
