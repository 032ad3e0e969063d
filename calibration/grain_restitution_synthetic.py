"""Calibration: recover the grains' coefficient of restitution from a synthetic
drop curve, and how far the gradient of a grain rollout can be trusted.

A grain (5 mm, 2650 kg/m^3, in air) dropped from 3 cm head-on onto a floor
particle (`grain_drop`, target="particle"), fixed dt = 0.5 ms: its height over
0.15 s (the impact at 0.078 s and the first rebound) is the "measured" curve
at e = 0.6; the fit starts at e = 0.4 and recovers e by gradient through the
rollout (Adam on the logit of e).

Then the loss and its gradient against the secant slope (e +- 1e-3) over a
range of restitutions, for the head-on drop and the drop into the dimple
between two floor particles: where a second impact falls inside the window
(low e), the loss is piecewise and its gradient stops describing it. And the
gradient against central differences over the collapse of a small column
(`granular_collapse`, 26 grains) for growing rollouts: each contact that
begins or ends inside a sub-step is a kink of the discrete rollout, and a
heap's grains make and break thousands.

Run: python calibration/grain_restitution_synthetic.py
(writes results/grain_restitution_synthetic*)
"""

import json
import pathlib

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax

import jaxmps
from jaxmps.calibration import Bounded, Curve, calibrate

HERE = pathlib.Path(__file__).parent
DROP = dict(
    dt=5e-4, drop_height=0.03, spacing=0.005, restitution=0.6, target="particle"
)
FIT_STEPS, SAVE_EVERY = 300, 10
TRUE, START = 0.6, 0.4
LANDSCAPE = (0.2, 0.3, 0.4, 0.5, 0.55, 0.65, 0.7, 0.8, 0.9)


def height_curve(case, restitution, n_steps=FIT_STEPS):
    params = eqx.tree_at(
        lambda p: p.grains.restitution, case.params, jnp.asarray(restitution)
    )
    obs = jaxmps.scenes.observe_probes(case.probes)
    out = jaxmps.simulate(case.scene, params, case.state, n_steps, SAVE_EVERY, obs)
    return out.saved["time"], out.saved["grain_height"]


def recover(case):
    t, y = height_curve(case, TRUE)
    res = calibrate(
        case,
        {"grains.restitution": Bounded(0.0, 1.0)},
        Curve(times=np.asarray(t), values=np.asarray(y)),
        "grain_height",
        FIT_STEPS,
        SAVE_EVERY,
        optimiser=optax.adam(optax.exponential_decay(0.3, 10, 0.5)),
        iterations=40,
        initial={"grains.restitution": START},
        progress=False,
    )
    value = float(np.ravel(res.values["grains.restitution"])[0])
    res.save(HERE / "results" / "grain_restitution_synthetic.json")
    res.plot(HERE / "results" / "grain_restitution_synthetic.png")
    return dict(
        true=TRUE,
        start=START,
        recovered=value,
        relative_error=value / TRUE - 1,
        iterations=res.iterations,
        best_iteration=res.best_iteration,
        loss_start=float(res.history["loss"][0]),
        loss_best=float(res.best_loss),
    )


def landscape():
    """The fit's loss, its gradient and the secant slope (e +- 1e-3) over
    `LANDSCAPE`, head-on and into the dimple."""
    rows = []
    for target in ("particle", "dimple"):
        case = jaxmps.scenes.grain_drop(**{**DROP, "target": target})
        _, measured = height_curve(case, TRUE)

        def loss(e, case=case, measured=measured):
            return jnp.mean((height_curve(case, e)[1] - measured) ** 2)

        value = jax.jit(loss)
        slope = jax.jit(jax.grad(loss))
        for e in LANDSCAPE:
            secant = (value(e + 1e-3) - value(e - 1e-3)) / 2e-3
            rows.append(
                dict(
                    target=target,
                    restitution=e,
                    loss=float(value(e)),
                    gradient=float(slope(e)),
                    secant=float(secant),
                )
            )
    return rows


def gradient_checks():
    """AD against central differences (relative step 1e-5) of a loss on the
    final positions of the column (friction)."""
    rows = []
    column = jaxmps.scenes.granular_collapse(
        column_width=0.02,
        column_height=0.03,
        spacing=0.005,
        floor_length=0.08,
        dt=5e-4,
    )
    index = column.state.grains.index
    for n in (20, 60, 150):

        def loss(mu, n=n):
            params = eqx.tree_at(lambda p: p.grains.friction, column.params, mu)
            out = jaxmps.simulate(column.scene, params, column.state, n, n)
            x = out.state.position[index]
            return jnp.mean(x[:, 0] ** 2) + jnp.mean(x[:, 1])

        rows.append(_compare("granular_collapse", "friction", n, loss, 0.5))
    return rows


def _compare(scene, field, n, loss, value):
    ad = float(jax.grad(loss)(jnp.asarray(value)))
    h = 1e-5 * value
    fd = float((loss(jnp.asarray(value + h)) - loss(jnp.asarray(value - h))) / (2 * h))
    return dict(
        scene=scene,
        field=field,
        steps=n,
        ad=ad,
        fd=fd,
        relative=abs(ad / fd - 1) if fd else float("inf"),
    )


def main():
    jax.config.update("jax_enable_x64", True)
    (HERE / "results").mkdir(exist_ok=True)
    case = jaxmps.scenes.grain_drop(**DROP)
    fit = recover(case)
    out = {"fit": fit, "landscape": landscape(), "gradient_checks": gradient_checks()}
    path = HERE / "results" / "grain_restitution_synthetic_summary.json"
    path.write_text(json.dumps(out, indent=2))
    print(json.dumps(out, indent=2))


if __name__ == "__main__":
    main()
