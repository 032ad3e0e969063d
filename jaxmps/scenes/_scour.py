"""Local scour below a groundsill: seed 002's E-MPS-DEM simulation of Case 2-2
(Ch. 6), a jet over a drop digging a hole in a bed of DEM grains."""

from ._case import Case
from ._common import resolve
from ._flume import DEFAULTS as _FLUME
from ._flume import flume
from ._washout import fed_depth

# Seed 002's Case 2-2 hole after 10 min (experiment) and its own E-MPS-DEM
# simulation at 50 s (d = l0 = 1 mm): length L and deepest point Z_d [m].
MEASURED_SCOUR = {"experiment": (0.425, 0.049), "seed simulation": (0.435, 0.058)}

LOCAL_SCOUR = {
    **{k: v for k, v in _FLUME.items() if k not in ("dim", "spacing", "t_end")},
    "discharge": 0.012,
    "inflow_depth": None,  # None: the critical depth (q^2 / g)^(1/3)
    # seed 002 Case 2-2: main body 3 cm, a 2 cm drop, apron 10 cm, a 29 cm
    # flat reach, a 0.5 m transition falling by Delta H = 2 cm (1/25), then
    # the lowered bed, shortened to 20 cm, to a free overfall.
    "crest_length": 0.03,
    "step_height": 0.02,
    "apron_length": 0.10,
    "reach_length": 0.29,
    "transition_length": 0.5,
    "bed_lowering": 0.02,
    "bed_length": 1.12,
    # Grains over 37.5 cm from the apron's end (the reach and the top of the
    # transition), 7 cm deep (the seed: "enough for the observed lowering").
    "movable_length": 0.375,
    "movable_depth": 0.07,
    # seed 002 Ch. 6: submerged specific gravity R = 1.25, mu = 0.577; the
    # stiffness None: the seed's rule at the run's step (see local_scour).
    "grain_density": 2250.0,
    "friction": 0.577,
    "release_time": 10.0,  # the seed's spin-up with the grains fixed
    "solver": "explicit",
    "sound_speed": 10.0,
    "wall_pressure": "facing",
    "spacing": 0.001,
    "dim": 2,
    "t_end": 60.0,
}


def local_scour(**overrides) -> Case:
    """Seed 002's local scour (Case 2-2, its Ch. 6 E-MPS-DEM simulation): the
    flume's groundsill (crest `crest_length`, a drop of `step_height`, an apron
    of `apron_length`), a reach and a transition falling by `bed_lowering`
    (Delta H) to a free overfall at `bed_length`, fed at `discharge` q over the
    crest at the critical depth; from the apron's end a movable bed of DEM
    grains of the spacing's diameter (`movable_length`, `movable_depth`,
    seed 002's packed bed, attached to the bed as walls until the flow moves
    them) on the fixed bed; explicit E-MPS with the wall pressure copied from
    the facing fluid. The defaults are the seed's: l0 = d = 1 mm, R = 1.25, mu
    = 0.577, a 10 s spin-up with the grains fixed (here: feeling no flow,
    settling under their own weight), then 50 s.

    The stiffness defaults to seed 002's rule at the run's step (`bodies.
    rule_stiffness` of a grain's submerged mass; 12.9 N/m at the seed's 1 mm
    and 5e-5 s), which keeps the DEM on one sub-step: a bed under a flow,
    whose grains meet at the flow's speeds, not at free fall (the flume's
    movable bed with the explicit solver).

    Probes: the flume's, and `scour_depth`, `scour_length` (`BedLowering`:
    the hole's deepest lowering of the bed below its initial surface and its
    length, where the bed is lowered by more than one grain). The seed's
    hole after 50 s: L = 43.5 cm, Z_d = 5.8 cm; the experiment's after 10 min
    42.5 / 4.9 cm (`MEASURED_SCOUR`). The hole depends on the grain size, which
    is the spacing here."""
    c = resolve("local_scour", LOCAL_SCOUR, overrides)
    if int(c["dim"]) != 2:
        raise ValueError("local_scour is 2-D only for now (dim=2).")
    if c["inflow_depth"] is None:
        c["inflow_depth"] = (c["discharge"] ** 2 / c["gravity"]) ** (1 / 3)
    case = flume(**c)
    params = fed_depth(case)
    return Case(
        "local_scour",
        case.scene,
        params,
        case.state,
        case.probes,
        case.t_end,
        {**case.config, "stiffness": _stiffness(case)},
    )


def _stiffness(case: Case) -> float | None:
    """The grains' stiffness the case took (None without a movable bed)."""
    grains = case.params.grains
    return None if grains is None else float(grains.stiffness)
