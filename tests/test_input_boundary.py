"""Bad input is refused at the boundary where it enters, by the name the user gave
it: scene settings, sizes, sweeps and calibration members, restarts."""

import numpy as np
import pytest

import jaxmps

# Each refused setting and the words its message must hold: the setting's name
# and what it accepts.
REFUSED_SETTINGS = {
    "gravity=nan": ({"gravity": float("nan")}, r"gravity must be finite and >= 0"),
    "gravity=-9.81": ({"gravity": -9.81}, r"gravity must be finite and >= 0"),
    "courant=0": ({"courant": 0}, r"courant must be finite, in \(0, 1\]"),
    "courant=inf": ({"courant": float("inf")}, r"courant must be"),
    "density=-1000": ({"density": -1000}, r"density must be positive"),
    "viscosity=-1e-6": ({"viscosity": -1e-6}, r"viscosity must be finite and >= 0"),
    "dt=0": ({"dt": 0.0}, r"dt must be positive"),
    "dt=nan": ({"dt": float("nan")}, r"dt must be positive"),
    "beta=1.5": ({"beta": 1.5}, r"beta must be finite, in \(0, 1\]"),
    "rtol=0": ({"rtol": 0.0}, r"rtol must be finite, in \(0, 1\)"),
    "max_iterations=0": ({"max_iterations": 0}, r"max_iterations must be"),
    "max_iterations=1e30": ({"max_iterations": 1e30}, r"max_iterations must be"),
    "max_iterations=inf": ({"max_iterations": float("inf")}, r"'max_iterations'"),
    "depth=0": ({"depth": 0.0}, r"depth must be positive"),
    "width=-inf": ({"width": -float("inf")}, r"width must be positive"),
    "spacing=1e400 (an integer beyond floats)": (
        {"spacing": 10**400},
        r"spacing must be positive and finite",
    ),
    "t_end=nan": ({"t_end": float("nan")}, r"t_end must be positive"),
    "sound_speed as a word": ({"sound_speed": "fast"}, r"'sound_speed'.*a number"),
    "gravity=0 with a derived dt": (
        {"gravity": 0.0},
        r"gravity=0.0 leaves no velocity scale.*give `dt_max`",
    ),
}


@pytest.mark.parametrize("what", list(REFUSED_SETTINGS))
def test_a_refused_setting_is_named(what):
    overrides, message = REFUSED_SETTINGS[what]
    with pytest.raises(ValueError, match=message):
        jaxmps.scenes.hydrostatic(**{"spacing": 0.05, **overrides})


def test_settings_of_other_scenes_are_checked_by_the_same_table():
    with pytest.raises(ValueError, match=r"angle must be finite, in \(-90, 90\)"):
        jaxmps.scenes.friction_tilt(angle=90.0)
    with pytest.raises(ValueError, match=r"velocity=0 leaves no velocity scale"):
        jaxmps.scenes.block_impact(velocity=0.0)
    with pytest.raises(ValueError, match=r"density_ratio must be positive"):
        jaxmps.scenes.floating_box(density_ratio=0.0)


def test_every_word_setting_has_its_words():
    """Each scene's word settings (beyond the common ones, checked in `resolve`)
    are in the table of words, with their defaults among them."""
    from jaxmps.scenes import COMMON
    from jaxmps.scenes._common import _CHOICES

    for scene, defaults in jaxmps.scenes.available().items():
        for name, default in defaults.items():
            if isinstance(default, str) and name not in COMMON:
                assert name in _CHOICES, f"{scene}: word setting {name!r} has no words"
                assert default in _CHOICES[name], f"{scene}: {name}={default!r}"


# A misspelt word is refused even where the scene's other settings leave it
# unused (a rigid block's `contact`, a flume's `friction_normal` without blocks).
MISSPELT_WORDS = [
    ("block_impact", "contact", "psuh"),
    ("friction_tilt", "contact", "bogus"),
    ("flume", "friction_normal", "weight"),
    ("block_stack", "layout", "pile"),
    ("sloshing_tank", "slope_wall", "type3"),
    ("wave_tank", "end", "sand"),
    ("tsunami_quay", "ship_body", "foam"),
]


@pytest.mark.parametrize(("scene", "name", "word"), MISSPELT_WORDS)
def test_a_misspelt_word_is_refused_by_name(scene, name, word):
    with pytest.raises(ValueError, match=rf"{name}='{word}' is not a choice.*valid: "):
        jaxmps.scenes.build(scene, **{name: word})


@pytest.mark.parametrize("scene", ["dam_break", "wave_tank"])
@pytest.mark.parametrize("gauge_x", [-0.1, 100.0])
def test_a_gauge_outside_the_tank_is_refused(scene, gauge_x):
    with pytest.raises(ValueError, match=r"gauge_x=.* lies outside the tank"):
        jaxmps.scenes.build(scene, gauge_x=gauge_x)


def test_a_box_off_its_reach_names_box_x():
    with pytest.raises(ValueError, match=r"box_x .* must exceed column_width"):
        jaxmps.scenes.dam_break_box(box_x=0.05)


@pytest.mark.parametrize(
    ("scene", "settings", "name"),
    [
        ("hydrostatic", dict(spacing=1.0), "width"),
        ("floating_box", dict(spacing=0.02, box_height=0.009), "box_height"),
        ("block_stack", dict(spacing=0.1, block_size=0.04), "block_size"),
        ("dam_break", dict(spacing=0.05, column_width=0.02), "column_width"),
    ],
)
def test_a_length_under_half_a_spacing_is_refused_by_name(scene, settings, name):
    """Such a length would be built one spacing long (a 0.2 m tank at spacing 1 m
    became a 1 m tank of one particle)."""
    with pytest.raises(ValueError, match=rf"{name}=.* under half the particle spacing"):
        jaxmps.scenes.build(scene, **settings)


def test_a_length_of_half_a_spacing_or_more_is_built_in_whole_spacings():
    case = jaxmps.scenes.hydrostatic(spacing=0.05, width=0.2, depth=0.03)
    assert case.config["depth"] == pytest.approx(0.05)  # 0.6 spacings: one


@pytest.mark.parametrize("name", ["flume", "local_scour", "block_washout"])
def test_a_2d_flume_scene_asked_for_3d_names_itself(name):
    with pytest.raises(ValueError, match=f"^{name} is 2-D"):
        jaxmps.scenes.build(name, dim=3)


@pytest.mark.parametrize(
    "scene, settings",
    [
        ("friction_tilt", dict(block_size=0.3, spacing=0.1)),
        ("block_impact", dict(block_size=0.3, spacing=0.1)),
        ("block_stack", dict(block_size=0.3, block_height=0.3, spacing=0.05)),
    ],
)
def test_a_block_of_any_size_gets_a_tank_of_whole_spacings(scene, settings):
    """The dry block scenes make room above their blocks of 1.2 times their top;
    for a 0.3 m block that was not a whole number of spacings, and the build
    failed inside the lattice generator without naming a setting."""
    case = jaxmps.scenes.build(scene, **settings)
    kind = np.asarray(case.state.kind)
    wall = np.asarray(case.state.position)[
        (kind == int(jaxmps.Kind.WALL)) | (kind == int(jaxmps.Kind.DUMMY))
    ]
    rows = wall[:, 1] / settings["spacing"] - 0.5  # the lattice's rows: whole
    np.testing.assert_allclose(rows, np.round(rows), atol=1e-9)


def test_gravity_zero_runs_with_a_given_dt():
    case = jaxmps.scenes.hydrostatic(spacing=0.05, gravity=0.0, dt=1e-3)
    assert float(case.params.dt) == pytest.approx(1e-3)
    np.testing.assert_array_equal(np.asarray(case.params.gravity), [0.0, 0.0])


def test_every_scene_setting_has_a_rule_or_is_a_word():
    """The table covers every numeric setting of every scene (a new setting must be
    given its range); a box or a list of regions is checked where it is read."""
    from jaxmps.scenes._common import RULES, STRUCTURED

    for scene, defaults in jaxmps.scenes.available().items():
        for name, default in defaults.items():
            if isinstance(default, (bool, str)) or name in ("dim", *STRUCTURED):
                continue
            assert name in RULES, f"{scene}: setting {name!r} has no rule"


@pytest.mark.parametrize("scene", ["dam_break", "hydrostatic"])
def test_a_huge_scene_is_refused_before_allocating(scene):
    with pytest.raises(ValueError, match=r"spacing=1e-05 m asks for 4.*e\+08 partic"):
        jaxmps.scenes.build(scene, spacing=1e-5)


def test_the_particle_limit_is_configurable(monkeypatch):
    monkeypatch.setenv("JAXMPS_MAX_PARTICLES", "50")
    with pytest.raises(ValueError, match=r"above the limit of 50.*raise `spacing`"):
        jaxmps.scenes.hydrostatic(spacing=0.02)
    monkeypatch.setenv("JAXMPS_MAX_PARTICLES", "1e6")
    jaxmps.scenes.hydrostatic(spacing=0.05)
    for bad in ("-5", "0", "abc", "inf"):
        monkeypatch.setenv("JAXMPS_MAX_PARTICLES", bad)
        with pytest.raises(ValueError, match=r"is not a number of particles.*unset"):
            jaxmps.scenes.hydrostatic(spacing=0.05)


def test_an_unknown_particle_kind_is_refused():
    position = np.array([[0.1, 0.1], [0.2, 0.1]])
    scene = jaxmps.make_scene(position, 0.1, ([0, 0], [1, 1]))
    with pytest.raises(ValueError, match=r"kind holds \[9\].*valid: 0 \(fluid\)"):
        jaxmps.make_state(scene, position, [0, 9])


# ------------------------------------------------------------ one entry, one rule


def test_inputs_refused_alike_by_every_entry_point():
    """Values one entry point refused and another accepted, or clamped silently."""
    from jaxmps.calibration import Curve

    position = np.array([[0.1, 0.1], [0.2, 0.1]])
    with pytest.raises(ValueError, match="spacing must be positive and finite"):
        jaxmps.make_scene(position, 1e300, ([0, 0], [1, 1]))
    with pytest.raises(ValueError, match=r"Params.gravity must be finite"):
        jaxmps.make_params(2, dt=1e-3, gravity=float("nan"))
    with pytest.raises(ValueError, match=r"Params.density must be positive and fin"):
        jaxmps.make_params(2, dt=1e-3, density=float("inf"))
    with pytest.raises(ValueError, match=r"Params.relaxation_step must be positive"):
        jaxmps.make_params(2, dt=1e-3, relaxation_step=-1e-3)
    with pytest.raises(ValueError, match=r"Params.rigid.density must be positive"):
        jaxmps._params.RigidParams(
            density=np.array([np.inf]), mu_static=np.zeros(1), mu_kinetic=np.zeros(1)
        )
    with pytest.raises(ValueError, match=r"Curve.values must be finite"):
        Curve(times=np.array([0.0, 1.0]), values=np.array([np.nan, 1.0]))
    case = jaxmps.scenes.hydrostatic(spacing=0.05)
    with pytest.raises(ValueError, match=r"chunk must be a whole number >= 1"):
        jaxmps.sweep(case, {"viscosity": np.ones(2) * 1e-6}, 2, 2, chunk=0)
    with pytest.raises(ValueError, match=r"iterations must be at least 1"):
        jaxmps.calibrate(
            case,
            {"viscosity": None},
            Curve(times=np.array([0.0, 1.0]), values=np.zeros(2)),
            "water_level",
            2,
            2,
            iterations=0,
        )


def test_a_spin_up_that_fails_is_refused_naming_settle():
    """A scene that settles its bodies before their release says so when the
    settling stops (here dry blocks 500x lighter than water, whose contact asks
    for a step below the smallest), instead of a runtime error from inside JIT."""
    with pytest.raises(ValueError, match=r"settle=0.3 s\) stopped at t = .*settle=0"):
        jaxmps.scenes.block_stack(density_ratio=0.002)
