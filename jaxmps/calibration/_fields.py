"""Addressing Params fields by dotted name ("viscosity", "inflow.velocity")."""

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
    return (
        f"Unknown Params field {name!r}. Valid fields: "
        f"{', '.join(field_names(params))}."
    )
