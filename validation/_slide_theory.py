"""Linear potential flow of a block sliding along the floor of a closed 2-D tank
under tilted gravity (seed 002's T10 in still water): the water's added mass and
the block's travel x(t) after its release from rest.

The tank is `length` long with vertical end walls; the floor is the slope, gravity
tilted by theta (g sin theta down the floor, along +x), so the free surface rises
along x with slope tan theta, `depth` above the floor at the block's centre. The
block (`width` along the floor, `height` tall, `x0` from the upper wall) slides
along the floor with speed U(t); the water is inviscid and starts at rest. With
the velocity potential phi (water velocity grad phi; phi = 0 on the free surface
at rest):

- on the block's faces d(phi)/dn = U n_x; on the walls and the floor 0;
- on the free surface, linearised: d(phi)/dt = -g zeta, d(zeta)/dt = d(phi)/dn
  (zeta the rise normal to the surface);
- the block: (M + m_inf) dU/dt = F - rho d/dt (the surface's share of the force),
  F = (M - rho V) g (sin theta - mu cos theta) with the submerged weight as the
  Coulomb law's normal force, m_inf the added mass with phi = 0 on the surface
  (the impulsive limit, which holds at t = 0+). As the surface rises the added
  mass grows towards the rigid-lid value and the block slows.

Finite volumes on a square grid of side `cell` (the block and walls on cell
faces, the surface cut at its true height in the last cell below it), the linear
system exponentiated exactly in time (scipy.linalg.expm). Quantities per unit
width and per unit water density.

Checks (run this file): the added mass converges with the cell size; a thin plate
standing on the floor of deep, wide water has the flat plate's added mass (its
image makes a plate of twice the height: m = pi H^2 / 2, Lamb); a square block on
the floor has the tabulated value for a 2:1 rectangle (its image; C_A = 1.36,
DNV-RP-C205 Table A-1: m = 1.36 pi H^2 / 2); and the travel converges.
"""

import math

import numpy as np
import scipy.linalg
import scipy.sparse as sparse
import scipy.sparse.linalg as sparse_linalg

G = 9.81


def _tank(length, x0, width, height, surface, cell):
    """Cell centres, the fluid and block masks and the fluid cells' numbering."""
    nx = round(length / cell)
    top = max(surface(0.0), surface(length))
    ny = int(math.ceil(top / cell)) + 1
    xc = (np.arange(nx) + 0.5) * cell
    yc = (np.arange(ny) + 0.5) * cell
    X, Y = np.meshgrid(xc, yc, indexing="ij")
    block = (X > x0) & (X < x0 + width) & (Y < height)
    fluid = (Y < surface(X)) & ~block
    number = -np.ones((nx, ny), int)
    number[fluid] = np.arange(int(fluid.sum()))
    return xc, yc, block, fluid, number


def operators(length, x0, width, height, surface, cell, rigid_lid=False, response=True):
    """The discrete problem: the unit-speed potential phi_U (phi = 0 on the surface),
    the added mass m_inf, and what the surface's potential does to the block's
    force and to the cells under the surface. `surface(x)`: its height."""
    xc, yc, block, fluid, number = _tank(length, x0, width, height, surface, cell)
    nx, ny = block.shape
    n = int(fluid.sum())
    ix, iy = np.nonzero(fluid)
    k = number[ix, iy]
    rows, cols = [], []
    diag = np.zeros(n)
    rhs = np.zeros(n)  # the block's prescribed flux, unit speed
    weight = np.zeros(n)  # sum over the block's faces of phi n_x (its force)
    top_cell, top_gap = np.zeros(0, int), np.zeros(0)
    for di, dj in ((1, 0), (-1, 0), (0, 1), (0, -1)):
        ix2, iy2 = ix + di, iy + dj
        inside = (ix2 >= 0) & (ix2 < nx) & (iy2 >= 0) & (iy2 < ny)
        other = np.full(ix.shape, -1)
        other[inside] = number[ix2[inside], iy2[inside]]
        water = other >= 0
        rows.append(k[water])
        cols.append(other[water])
        np.add.at(diag, k[water], -1.0)
        solid = np.zeros(ix.shape, bool)
        solid[inside] = block[ix2[inside], iy2[inside]]
        # The water at the block's face moves with it: flux di * cell leaves the cell.
        np.add.at(rhs, k[solid], -di * cell)
        np.add.at(weight, k[solid], di * cell)
        if dj == 1 and not rigid_lid:
            free = ~water & ~solid
            top_cell = k[free]
            top_gap = np.maximum(surface(xc[ix[free]]) - yc[iy[free]], 0.05 * cell)
            np.add.at(diag, top_cell, -cell / top_gap)
    rows, cols = np.concatenate(rows), np.concatenate(cols)
    A = sparse.csr_matrix((np.ones(rows.size), (rows, cols)), shape=(n, n))
    A = A + sparse.diags(diag)
    if rigid_lid:  # pure Neumann: pin the constant
        A = A + sparse.csr_matrix(([1.0], ([0], [0])), shape=(n, n))
    lu = sparse_linalg.splu(A.tocsc())
    phi_u = lu.solve(rhs)
    out = {"m_inf": float(weight @ phi_u), "phi_u_top": phi_u[top_cell]}
    if rigid_lid or not response:
        return out
    # The surface's potential phi_s enters a top cell as + (cell / gap) phi_s; its
    # response under the surface and its share of the block's force, by columns.
    s = top_cell.size
    scale = cell / top_gap
    green_top = np.zeros((s, s))
    for start in range(0, s, 64):
        cols_s = np.arange(start, min(s, start + 64))
        b = np.zeros((n, cols_s.size))
        b[top_cell[cols_s], np.arange(cols_s.size)] = -scale[cols_s]
        green_top[:, cols_s] = lu.solve(b)[top_cell]
    force = -lu.solve(weight)[top_cell] * scale  # A symmetric: w^T A^-1 b
    return {**out, "green_top": green_top, "force": force, "gap": top_gap}


def slide(
    *,
    length=3.0,
    x0=0.3,
    width=1.0,
    height=1.0,
    depth=1.5,
    tan_theta=0.5,
    density_ratio=1.5,
    mu=0.0,
    times=(0.1, 0.2, 0.3),
    cell=0.01,
):
    """The block's travel [m] at `times` [s] after its release, its initial
    acceleration and the added masses (impulsive and rigid-lid) per rho [m^2]."""
    cos = 1.0 / math.sqrt(1.0 + tan_theta**2)
    sin = tan_theta * cos
    level = depth - tan_theta * (x0 + width / 2)

    def surface(x):
        return level + tan_theta * x

    op = operators(length, x0, width, height, surface, cell)
    lid = operators(length, x0, width, height, surface, cell, rigid_lid=True)
    mass = density_ratio * width * height
    drive = max(0.0, (density_ratio - 1) * width * height * G * (sin - mu * cos))
    s = op["gap"].size
    inertia = mass + op["m_inf"]
    # y = [x, U, phi_s (s), zeta (s), 1]
    K = np.zeros((2 * s + 3, 2 * s + 3))
    K[0, 1] = 1.0
    K[1, 2 + s : 2 + 2 * s] = G * op["force"] / inertia
    K[1, -1] = drive / inertia
    K[2 : 2 + s, 2 + s : 2 + 2 * s] = -G * np.eye(s)
    rate = cos / op["gap"]
    K[2 + s : 2 + 2 * s, 1] = -rate * op["phi_u_top"]
    K[2 + s : 2 + 2 * s, 2 : 2 + s] = rate[:, None] * (np.eye(s) - op["green_top"])
    y0 = np.zeros(2 * s + 3)
    y0[-1] = 1.0
    travel = [float((scipy.linalg.expm(K * t) @ y0)[0]) for t in times]
    return {
        "travel": travel,
        "times": list(times),
        "initial_acceleration": drive / inertia,
        "added_mass_impulsive": op["m_inf"],
        "added_mass_rigid_lid": lid["m_inf"],
        "mass": mass,
    }


def _checks():
    print("added mass of the T10 block (1 m square, 3 m tank, 1.5 m deep):")
    for cell in (0.04, 0.02, 0.01):
        r = slide(cell=cell)
        print(
            f"  cell {cell}: m_inf {r['added_mass_impulsive']:.4f} rigid lid "
            f"{r['added_mass_rigid_lid']:.4f}, travel {np.round(r['travel'], 6)}"
        )

    def alone(width, cell, size=16.0):
        def surface(x):
            return size / 2 + 0 * x

        args = (size, (size - width) / 2, width, 1.0, surface, cell)
        return operators(*args, response=False)["m_inf"]

    for cell in (0.04, 0.02):
        plate, square = alone(2 * cell, cell), alone(1.0, cell)
        print(
            f"  cell {cell}: a plate two cells thick {plate:.4f} (thin: pi / 2 = "
            f"{math.pi / 2:.4f}); square {square:.4f} (1.36 pi / 2 = "
            f"{1.36 * math.pi / 2:.4f}), in water 16 m wide and 8 m deep"
        )


if __name__ == "__main__":
    _checks()
