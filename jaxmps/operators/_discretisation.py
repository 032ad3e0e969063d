"""The particle discretisation every operator is built on."""

import equinox as eqx

from ._weight import AbstractWeight


class Discretisation(eqx.Module):
    """The lattice and kernel of a simulation: what every MPS operator needs.

    Static (Python numbers and a weight object); a Scene holds one
    (`Scene.discretisation`). Build it with `jaxmps.make_scene`, which derives n0
    and lambda from the weight on the regular lattice.

    Attributes:
        dim: spatial dimension (2 or 3); the last axis is vertical.
        spacing: initial particle spacing l0 [m].
        r_e: influence radius [m].
        n0: reference particle number density of the lattice.
        lam: Laplacian coefficient lambda [m^2].
        weight: the weight function w(r) of the number density, the Laplacian and
            the gradient.
    """

    dim: int
    spacing: float
    r_e: float
    n0: float
    lam: float
    weight: AbstractWeight

    def __check_init__(self):
        if self.dim not in (2, 3):
            raise ValueError(f"Discretisation.dim must be 2 or 3, got {self.dim}.")
        if not (self.spacing > 0 and self.r_e > self.spacing):
            raise ValueError(
                "Discretisation needs spacing > 0 and r_e > spacing, got "
                f"spacing={self.spacing}, r_e={self.r_e}."
            )
        if not (self.n0 > 0 and self.lam > 0):
            raise ValueError("Discretisation.n0 and Discretisation.lam must be > 0.")

    @property
    def volume(self) -> float:
        """Volume of one particle, l0^d [m^d] (an area per unit width in 2-D)."""
        return self.spacing**self.dim
