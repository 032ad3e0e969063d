"""The step as a pipeline of stages: a scene compiles only the stages of the
physics it contains, and the fluid stages reach the body models only through the
coupling records."""

import jax

import jaxmps


def test_scene_without_bodies_compiles_no_body_code():
    """A pure-fluid scene pays nothing for the rigid component: its step program
    has no `rigid` stage, a body scene's has."""
    fluid = jaxmps.scenes.hydrostatic(spacing=0.04)
    body = jaxmps.scenes.block_impact(spacing=0.5)

    def scopes(case):
        closed = jax.make_jaxpr(lambda p, s: jaxmps._step._step(case.scene, p, s))(
            case.params, case.state
        )
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

    assert "pressure" in scopes(fluid) and "pressure" in scopes(body)
    assert "rigid" not in scopes(fluid)
    assert "rigid" in scopes(body)
    # The coupling stage is empty without body models: no per-particle densities,
    # no internal-pair masks.
    assert "coupling" not in scopes(fluid)
    assert "coupling" in scopes(body)


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
