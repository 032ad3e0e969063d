"""Linear potential-flow heave of a floating 2-D rectangle (beam B, draft T) in water
of depth h: added mass a33(w) and radiation damping b33(w) per unit length, by
eigenfunction matching (the fluid under the keel in cosine modes plus the particular
solution of the moving bottom, the fluid outside in the propagating and evanescent
modes, matched in a Galerkin sense at x = +-B/2), and the free heave it gives: the
natural frequency w_n of w^2 (m + a33(w)) = rho g B and the damping ratio
b33 / (2 (m + a33) w_n); and the free decay itself in the time domain (the box
released from rest at an offset, in open water), which no single damped cosine
describes since a33 and b33 vary with frequency.

Checks (run this file): the damping from the pressure equals the damping from the
energy the radiated waves carry off; the results do not move when the number of
modes is raised; the time-domain decay with frequency-independent coefficients is
the damped oscillator's, and the box's moves by less than 1e-3 of the offset when
its frequency grid is refined and extended.
"""

import numpy as np

G = 9.81


def _bisect(f, lo, hi, tol=1e-13):
    flo = f(lo)
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        fmid = f(mid)
        if (fmid > 0) == (flo > 0):
            lo, flo = mid, fmid
        else:
            hi = mid
        if hi - lo < tol * max(1.0, abs(hi)):
            break
    return 0.5 * (lo + hi)


def _wavenumbers(K, h, modes):
    """k0 of k tanh(k h) = K and the evanescent k_m of k tan(k h) = -K."""
    k0 = _bisect(lambda k: k * np.tanh(k * h) - K, 1e-12, K + 10.0 / h + 10.0)
    km = [
        _bisect(
            lambda k: k * np.tan(k * h) + K,
            (m - 0.5) * np.pi / h + 1e-12,
            m * np.pi / h - 1e-12,
        )
        for m in range(1, modes + 1)
    ]
    return k0, np.array(km)


def heave_coefficients(B, T, h, w, modes=80, nodes=400, rho=1000.0):
    """(a33 [kg/m], b33 [kg/(m s)], b33 from the radiated energy) at frequency w."""
    b, H, K = 0.5 * B, h - T, w * w / G
    k0, km = _wavenumbers(K, h, modes)
    zq, wq = np.polynomial.legendre.leggauss(nodes)

    def integrate(f, a, c):
        z = 0.5 * (c - a) * zq + 0.5 * (c + a)
        return 0.5 * (c - a) * np.sum(wq * f(z), axis=-1)

    def outer(m):
        if m == 0:
            return lambda z: (
                np.exp(k0 * z)
                * (1 + np.exp(-2 * k0 * (z + h)))
                / (1 + np.exp(-2 * k0 * h))
            )
        return lambda z, k=km[m - 1]: np.cos(k * (z + h))

    n = modes + 1
    Z = [outer(m) for m in range(n)]
    decay = np.concatenate([[-1j * k0], km])
    norm = np.array([integrate(lambda z, f=f: f(z) ** 2, -h, 0) for f in Z])
    lam = np.arange(n) * np.pi / H
    zz = 0.5 * (h - T) * zq + 0.5 * (-T - h)
    ww = 0.5 * (h - T) * wq
    Zv = np.array([f(zz) for f in Z])
    Cv = np.array([np.cos(lam[q] * (zz + h)) for q in range(n)])
    L = (Zv * ww) @ Cv.T
    A = np.zeros((2 * n, 2 * n), complex)
    rhs = np.zeros(2 * n, complex)
    th = np.array([0.0] + [lam[j] * np.tanh(lam[j] * b) for j in range(1, n)])
    for p in range(n):  # normal velocity matched, projected on Z_p over (-h, 0)
        A[p, n + p] = -decay[p] * norm[p]
        A[p, 1:n] -= th[1:] * L[p, 1:]
        rhs[p] = -b / H * L[p, 0]

    def particular(z):
        return ((z + h) ** 2 - b * b) / (2 * H)

    for q in range(n):  # potential matched, projected on cos(lam_q (z + h))
        A[n + q, n : 2 * n] = L[:, q]
        A[n + q, q] = -H * (1.0 if q == 0 else 0.5)
        rhs[n + q] = integrate(
            lambda z: particular(z) * np.cos(lam[q] * (z + h)), -h, -T
        )
    sol = np.linalg.solve(A, rhs)
    inner, outer_amp = sol[:n], sol[n:]
    j = np.arange(1, n)
    force = 2 * (
        (H * b / 2 - b**3 / (6 * H))
        + inner[0] * b
        + np.sum(inner[1:] * (-1.0) ** j * np.tanh(lam[1:] * b) / lam[1:])
    )
    cg = (
        0.5
        * w
        / k0
        * (1 + (2 * k0 * h / np.sinh(2 * k0 * h) if 2 * k0 * h < 700 else 0))
    )
    amplitude = K * abs(outer_amp[0] * Z[0](0.0))
    return (
        rho * force.real,
        rho * w * force.imag,
        rho * 2 * G * cg * amplitude**2 / w**2,
    )


def free_heave(B, T, h, rho=1000.0, **kw):
    """(natural frequency w_n [rad/s], damping ratio, a33 / m at w_n) of a box of
    beam B and draft T floating freely in water of depth h (mass rho B T)."""
    m = rho * B * T

    def residual(w):
        return (
            w * w * (m + heave_coefficients(B, T, h, w, rho=rho, **kw)[0]) - rho * G * B
        )

    w_lo, w_hi = 0.3 * np.sqrt(2 * G / B), 1.6 * np.sqrt(2 * G / B)
    w_n = _bisect(residual, w_lo, w_hi, tol=1e-7)
    a33, b33, _ = heave_coefficients(B, T, h, w_n, rho=rho, **kw)
    return w_n, b33 / (2 * (m + a33) * w_n), a33 / m


def decay_from_coefficients(m, C, w, a, b, t):
    """Linear free decay x(t) / x(0) of a body of mass m and restoring
    coefficient C, held at x(0) and released from rest at t = 0, whose added mass
    a(w) and damping b(w) are given on the evenly spaced frequencies w (from near 0
    to well past resonance): x(t) = x0 (1 - C s(t)) with the step response
    s(t) = (2 / pi) int_0^inf Re H(w) sin(w t) / w dw of the transfer function
    H = 1 / (C - w^2 (m + a) + i w b) (causal, so its real part alone gives it),
    by the midpoint rule on w."""
    w, a, b = (np.asarray(v, dtype=np.float64) for v in (w, a, b))
    dw = w[1] - w[0]
    real = C - w * w * (m + a)
    re_h = real / (real * real + (w * b) ** 2)
    kernel = np.sin(np.outer(np.asarray(t, dtype=np.float64), w)) / w
    return 1.0 - C * (2.0 / np.pi) * (kernel @ re_h) * dw


def free_decay(B, T, h, t, rho=1000.0, w_max=15.0, dw=0.01, samples=240, **kw):
    """x(t) / x(0) of the box of beam B and draft T (mass rho B T) in water of
    depth h, released from rest at an offset x(0) from its equilibrium, in linear
    potential flow with no walls (the radiated waves never return): the Cummins
    decay through `decay_from_coefficients`, with a33 and b33 computed at
    `samples` frequencies up to w_max times the natural frequency and
    interpolated linearly onto a grid of spacing `dw` [rad/s]."""
    m, C = rho * B * T, rho * G * B
    w_n = free_heave(B, T, h, rho=rho, **kw)[0]
    top = w_max * w_n
    coarse = np.concatenate(
        [
            np.linspace(1e-3, 3 * w_n, samples * 2 // 3),
            np.linspace(3 * w_n, top, samples // 3)[1:],
        ]
    )
    ab = np.array([heave_coefficients(B, T, h, w, rho=rho, **kw)[:2] for w in coarse])
    fine = np.arange(0.5 * dw, top, dw)
    a = np.interp(fine, coarse, ab[:, 0])
    b = np.interp(fine, coarse, ab[:, 1])
    return decay_from_coefficients(m, C, fine, a, b, t)


if __name__ == "__main__":
    for B, T, h in ((0.2, 0.05, 0.4), (0.2, 0.05, 4.0), (1.0, 0.5, 20.0)):
        w = 0.9 * np.sqrt(2 * G / B)
        a, b, b_energy = heave_coefficients(B, T, h, w)
        a2, b2, _ = heave_coefficients(B, T, h, w, modes=160, nodes=800)
        w_n, zeta, ratio = free_heave(B, T, h)
        print(
            f"B={B} T={T} h={h}: b33 pressure/energy = {b / b_energy:.10f}, "
            f"a33 modes 80->160: {a2 / a - 1:+.1e}; T_n = {2 * np.pi / w_n:.4f} s "
            f"(T_n sqrt(g/B) = {2 * np.pi / w_n * np.sqrt(G / B):.3f}), "
            f"zeta = {zeta:.4f}, a33/m = {ratio:.3f}"
        )
    m, C, a0, b0 = 10.0, 1962.0, 14.0, 60.0
    w_n = np.sqrt(C / (m + a0))
    zeta = b0 / (2 * (m + a0) * w_n)
    t = np.linspace(0.0, 3.0, 301)
    w = np.arange(0.005, 15 * w_n, 0.01)
    x = decay_from_coefficients(m, C, w, np.full_like(w, a0), np.full_like(w, b0), t)
    w_d = w_n * np.sqrt(1 - zeta**2)
    exact = np.exp(-zeta * w_n * t) * (
        np.cos(w_d * t) + zeta / np.sqrt(1 - zeta**2) * np.sin(w_d * t)
    )
    box = free_decay(0.2, 0.05, 0.4, t)
    finer = free_decay(0.2, 0.05, 0.4, t, w_max=30.0, dw=0.005, samples=480)
    print(
        f"decay, constant a33 and b33 (zeta {zeta:.3f}): largest error"
        f" {np.abs(x - exact).max():.1e} of the offset; the box B=0.2 T=0.05 h=0.4,"
        f" grid refined: {np.abs(box - finer).max():.1e}"
    )
