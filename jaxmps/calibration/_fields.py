"""Addressing Params fields by dotted name ("viscosity", "inflow.velocity")."""

import difflib

import equinox as eqx


def get_field(params, name: str):
    obj = params
    for part in name.split("."):
        if obj is None or not hasattr(obj, part):
            raise ValueError(_unknown(params, name))
        obj = getattr(obj, part)
    return obj


def set_field(params, name: str, value):
    get_field(params, name)  # validates the name
    parts = name.split(".")

    def where(p):
        for part in parts:
            p = getattr(p, part)
        return p

    return eqx.tree_at(where, params, value)


def field_names(params, prefix: str = "") -> list[str]:
    names = []
    for key in params.__dataclass_fields__:
        value = getattr(params, key)
        if value is None:
            continue
        if isinstance(value, eqx.Module):
            names += field_names(value, f"{prefix}{key}.")
        else:
            names.append(f"{prefix}{key}")
    return names


def _unknown(params, name: str) -> str:
    names = field_names(params)
    close = difflib.get_close_matches(name, names, n=1, cutoff=0.8)
    hint = (
        f" Did you mean {close[0]!r}?"
        if close
        else " A setting that decides the particles (the spacing, the geometry, a "
        "porous region's porosity, which thins its water) is a scene setting, "
        "not a Params field: build one case per value "
        "(jaxmps.scenes.<scene>(setting=value)) and run them apart."
    )
    return f"Unknown Params field {name!r}. Valid fields: {', '.join(names)}.{hint}"
