"""Period and damping of a recorded free oscillation (host-side NumPy)."""

import numpy as np


def fit_damped_oscillation(times, values, period: float, *, spread: float = 0.2):
    """The damped cosine a + exp(-s t) (b cos w t + c sin w t) closest to a
    recorded free oscillation in least squares: its period 2 pi / w, damping
    ratio s / w, and the fit's residual (rms).

    A free decay's first reading (a sloshing mode released from rest, a body
    released from an offset): `period` is a guess, the search spans w within
    `spread` of 2 pi / period and s in [-1/period, 2/period] x 2 pi (negative: a
    growing record), on a grid refined twice about its best point; a, b, c are
    solved exactly at each (w, s). The damping ratio is s / w of the damped
    frequency (equal to the usual zeta to O(zeta^3)).

    Returns:
        (period [s], damping ratio, rms residual).
    """
    t = np.asarray(times, dtype=np.float64)
    y = np.asarray(values, dtype=np.float64)
    if t.shape != y.shape or t.ndim != 1 or len(t) < 4:
        raise ValueError(
            "times and values must be 1-D of the same length (at least 4 samples), "
            f"got {t.shape} and {y.shape}."
        )
    if not (period > 0 and 0 < spread < 1):
        raise ValueError(f"need period > 0 and 0 < spread < 1, got {period}, {spread}.")
    w0 = 2 * np.pi / period
    w_lo, w_hi = w0 * (1 - spread), w0 * (1 + spread)
    s_lo, s_hi = -w0 / (2 * np.pi), 2 * w0 / (2 * np.pi)
    best = None
    for _ in range(3):
        for w in np.linspace(w_lo, w_hi, 161):
            for s in np.linspace(s_lo, s_hi, 81):
                e = np.exp(-s * t)
                basis = np.stack(
                    [np.ones_like(t), e * np.cos(w * t), e * np.sin(w * t)], 1
                )
                coef, *_ = np.linalg.lstsq(basis, y, rcond=None)
                r = float(np.sum((basis @ coef - y) ** 2))
                if best is None or r < best[0]:
                    best = (r, w, s)
        _, w, s = best
        dw, ds = (w_hi - w_lo) / 16, (s_hi - s_lo) / 16
        w_lo, w_hi, s_lo, s_hi = w - dw, w + dw, s - ds, s + ds
    r, w, s = best
    return 2 * np.pi / w, s / w, float(np.sqrt(r / len(t)))
