"""The step as a pipeline of stages: a scene compiles only the stages of the
physics it contains, body models plug in through their interface, and the fluid
stages reach the body models only through the coupling records."""

import dataclasses
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jaxtyping import Array, Float, Int

import jaxmps
from jaxmps.bodies import AbstractBodyModel


class HeldParams(eqx.Module):
    density: Float[Array, ""]


class HeldState(eqx.Module):
    index: Int[Array, " m"]
    anchor: Float[Array, "m d"]
    load: Float[Array, " d"]


class Held(AbstractBodyModel):
    """A body model of the fewest lines: one body whose particles are held where
    they started; it records the pressure force the fluid exerted on them. `first`
    is its body number (after the other models' bodies)."""

    name: ClassVar[str] = "held"
    frame_fields: ClassVar[tuple[str, ...]] = ("load",)
    first: int = 0
    loads: ClassVar[list] = []  # what `advance` was handed, at trace time

    def check(self, params, state):
        pass

    def owner(self, state):
        n = state.position.shape[0]
        return jnp.full(n, -1, jnp.int32).at[state.held.index].set(self.first)

    def coupling(self, disc, params, state):
        owner = self.owner(state)
        density = jnp.where(owner >= 0, params.held.density, params.density)
        return jaxmps.Coupling(density=density, owner=owner, as_fluid=owner >= 0)

    def advance(self, disc, params, state, load):
        Held.loads.append(load)
        held = state.held
        force = -disc.volume * jnp.sum(load.gradient[held.index], axis=0)
        return dataclasses.replace(
            state,
            position=state.position.at[held.index].set(held.anchor),
            velocity=state.velocity.at[held.index].set(0.0),
            held=dataclasses.replace(held, load=force),
        )


class HeldScene(jaxmps.Scene):
    body_fields: ClassVar[tuple[str, ...]] = ("rigid", "held")
    held: Held | None = None


class HeldSceneParams(jaxmps.Params):
    held: HeldParams | None = None


class HeldSceneState(jaxmps.State):
    held: HeldState | None = None


def _fields(module) -> dict:
    return {f.name: getattr(module, f.name) for f in dataclasses.fields(module)}


def _hold(case, index, density=1000.0):
    """`case` with the particles `index` held by the mock model."""
    index = jnp.asarray(index, jnp.int32)
    first = 0 if case.scene.rigid is None else case.scene.rigid.count
    scene = HeldScene(**_fields(case.scene), held=Held(first=first))
    params = HeldSceneParams(**_fields(case.params), held=HeldParams(density))
    held = HeldState(
        index=index,
        anchor=case.state.position[index],
        load=jnp.zeros(case.state.position.shape[1]),
    )
    state = HeldSceneState(**_fields(case.state), held=held)
    return scene, params, state


def _scopes(scene, params, state) -> str:
    """The named scopes of every operation of the step program."""
    closed = jax.make_jaxpr(lambda p, s: jaxmps._step._step(scene, p, s))(params, state)
    names = set()

    def walk(jaxpr):
        for eqn in jaxpr.eqns:
            names.add(str(eqn.source_info.name_stack))
            for value in eqn.params.values():
                for sub in value if isinstance(value, (tuple, list)) else [value]:
                    inner = getattr(sub, "jaxpr", sub)
                    if hasattr(inner, "eqns"):
                        walk(inner)

    walk(closed.jaxpr)
    return " ".join(names)


def test_scene_without_bodies_compiles_no_body_code():
    """A pure-fluid scene pays nothing for a body model: its step program has no
    `rigid` (nor mock `held`) stage, a scene with the model has."""
    fluid = jaxmps.scenes.hydrostatic(spacing=0.04)
    body = jaxmps.scenes.block_impact(spacing=0.5)

    def scopes(case):
        return _scopes(case.scene, case.params, case.state)

    assert "advect" in scopes(fluid)
    assert "held" not in scopes(fluid)
    assert "held" in _scopes(*_hold(fluid, [0, 1]))
    assert "pressure" in scopes(fluid) and "pressure" in scopes(body)
    assert "rigid" not in scopes(fluid)
    assert "rigid" in scopes(body)
    # The coupling stage is empty without body models: no per-particle densities,
    # no internal-pair masks.
    assert "coupling" not in scopes(fluid)
    assert "coupling" in scopes(body)


def test_a_body_model_plugs_in_through_the_interface():
    """A new body model is its class, its three fields and one registry entry: the
    step hands it the `FluidLoad` of the pressure stage, the checks, frames and
    run files go through it, and its particles stay where it holds them."""
    case = jaxmps.scenes.hydrostatic(spacing=0.04)
    fluid = np.flatnonzero(np.asarray(case.state.kind) == int(jaxmps.Kind.FLUID))
    index = fluid[:3]  # the bottom row's first particles
    scene, params, state = _hold(case, index)
    Held.loads.clear()
    out = jaxmps.simulate(scene, params, state, 4, save_every=2)
    assert out.result == jaxmps.Result.successful
    assert Held.loads and all(isinstance(x, jaxmps.FluidLoad) for x in Held.loads)
    np.testing.assert_array_equal(out.state.position[index], case.state.position[index])
    np.testing.assert_array_equal(out.state.velocity[index], 0.0)
    # The fluid at rest pushes the bottom particles up against gravity.
    assert float(out.state.held.load[-1]) > 0
    assert out.saved.bodies["load"].shape == (2, 2)
    bad = dataclasses.replace(params, held=None)
    with pytest.raises(ValueError, match="Params.held and State.held must all be"):
        jaxmps.step(scene, bad, state)


def test_coupling_merges_the_models_slot_by_slot():
    """With two body models each particle takes the density, owner and pressure form
    of the model that owns it, the fluid's density elsewhere."""
    case = jaxmps.scenes.block_impact(spacing=0.5)
    rigid = np.asarray(case.state.rigid.body)
    free = np.flatnonzero((rigid < 0) & np.asarray(case.state.active))[:2]
    scene, params, state = _hold(case, free, density=3000.0)
    assert [m.name for m in scene.body_models] == ["rigid", "held"]
    coupling = jaxmps._step._coupling(scene, params, state)
    count = case.scene.rigid.count
    owner = np.where(rigid >= 0, rigid, -1)
    owner[free] = count
    np.testing.assert_array_equal(coupling.owner, owner)
    density = np.full(owner.shape, float(params.density))
    body_density = np.asarray(params.rigid.density)
    density[rigid >= 0] = body_density[rigid[rigid >= 0]]
    density[free] = 3000.0
    np.testing.assert_allclose(coupling.density, density, rtol=0, atol=0)
    # block_impact's rigid bodies take the pair form, the held body the fluid's.
    np.testing.assert_array_equal(
        coupling.as_fluid, np.isin(np.arange(len(owner)), free)
    )
    # Both models advance in one step: the held particles stay put.
    new, _ = jaxmps.step(scene, params, state)
    np.testing.assert_array_equal(new.position[free], state.position[free])
    assert new.held.load.shape == (case.scene.dim,)


def test_fluid_stages_import_nothing_from_the_body_models():
    """The fluid package reaches bodies only through the coupling records: none of
    its modules imports `jaxmps.bodies`."""
    import ast
    import pathlib

    package = pathlib.Path(jaxmps.fluid.__file__).parent
    for path in sorted(package.glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.ImportFrom):
                names = [node.module or ""] + [a.name for a in node.names]
            elif isinstance(node, ast.Import):
                names = [a.name for a in node.names]
            else:
                continue
            assert not any("bodies" in name for name in names), (path.name, names)
