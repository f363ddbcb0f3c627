"""Searching the response map for the impact that explains the measured features (eq. (7) of the paper).

- ``brute``: eq. (7) at every grid node (vectorized numpy), the minimum wins -- the paper's method; cost grows with
  the number of nodes.
- ``fast``: the map's nodes define smooth surfaces (bicubic Hermite patches with the derivatives of the not-a-knot
  tensor spline, fitted on at most :data:`FAST_NODES` nodes per axis); Gauss-Newton / Levenberg-Marquardt on eq. (7)
  runs from the best nodes of a fixed :data:`COARSE` × :data:`COARSE` lookup. Its cost does not depend on the grid
  size; the inner loop is compiled.

Along a pressure axis both searches interpolate with local cubic Lagrange weights (up to four layers).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from ...errors import ResponseMapError
from .database import ResponseMap, spline_basis

#: nodes per axis the fast surfaces are fitted on (every k-th node of larger maps)
FAST_NODES = 65
#: nodes per axis of the coarse lookup that starts the fast search
COARSE = 16
#: Gauss-Newton starts at most (best coarse nodes; a further one unless the fit is exact or 1000× better than its
#: lookup cost)
STARTS = 3
#: how far outside the map the fast search may look [fraction of each axis range]
EXTENSION = 0.25
#: answers this far beyond an edge still count as inside the map [fraction of the axis range]
EDGE_TOLERANCE = 0.005
SEARCHES = ("fast", "brute")


@njit(cache=True)
def pressure_weights(pressures, p):
    """First layer index, weights (4,) and count of the local cubic Lagrange interpolation at ``p`` [Pa]."""
    n = pressures.size
    w = np.zeros(4)
    if n == 1:
        w[0] = 1.0
        return 0, w, 1
    count = min(4, n)
    j = np.searchsorted(pressures, p) - 1  # layer below p
    j = min(max(j, 0), n - 2)
    k0 = min(max(j - 1, 0), n - count) if count == 4 else min(max(j - count // 2 + 1, 0), n - count)
    for a in range(count):
        value = 1.0
        for b in range(count):
            if b != a:
                value *= (p - pressures[k0 + b]) / (pressures[k0 + a] - pressures[k0 + b])
        w[a] = value
    return k0, w, count


@njit(cache=True)
def _cell(axis, x):
    i = np.searchsorted(axis, x) - 1
    i = min(max(i, 0), axis.size - 2)
    h = axis[i + 1] - axis[i]
    return i, (x - axis[i]) / h, h


@njit(cache=True)
def _hermite(t, out, slope):
    """Cubic Hermite basis (h00, h10, h01, h11) at t into ``out``, its derivatives w.r.t. t into ``slope``."""
    t2 = t * t
    t3 = t2 * t
    out[0], out[1], out[2], out[3] = 2 * t3 - 3 * t2 + 1, t3 - 2 * t2 + t, -2 * t3 + 3 * t2, t3 - t2
    slope[0], slope[1], slope[2], slope[3] = 6 * t2 - 6 * t, 3 * t2 - 4 * t + 1, -6 * t2 + 6 * t, 3 * t2 - 2 * t


@njit(cache=True)
def surface(herm, xm, xv, k0, w, count, m, v, out, dm, dv, basis):
    """Feature surfaces at (m [kg], v [m/s]) and their partial derivatives, pressure-weighted over layers.

    ``herm`` has shape (features, pressures, n_m, n_v, 4): value, ∂/∂m, ∂/∂v, ∂²/∂m∂v at the nodes; ``basis``
    is a (4, 4) work array.
    """
    i, t, hm = _cell(xm, m)
    j, s, hv = _cell(xv, v)
    _hermite(t, basis[0], basis[1])
    _hermite(s, basis[2], basis[3])
    for f in range(herm.shape[0]):
        val = 0.0
        gm = 0.0
        gv = 0.0
        for q in range(count):
            wq = w[q]
            k = k0 + q
            for a in range(2):
                ma = basis[0, 2 * a]
                mb = basis[0, 2 * a + 1] * hm
                da = basis[1, 2 * a]
                db = basis[1, 2 * a + 1] * hm
                for b in range(2):
                    va = basis[2, 2 * b]
                    vb = basis[2, 2 * b + 1] * hv
                    ea = basis[3, 2 * b]
                    eb = basis[3, 2 * b + 1] * hv
                    c0 = herm[f, k, i + a, j + b, 0] * wq
                    c1 = herm[f, k, i + a, j + b, 1] * wq
                    c2 = herm[f, k, i + a, j + b, 2] * wq
                    c3 = herm[f, k, i + a, j + b, 3] * wq
                    val += ma * va * c0 + mb * va * c1 + ma * vb * c2 + mb * vb * c3
                    gm += da * va * c0 + db * va * c1 + da * vb * c2 + db * vb * c3
                    gv += ma * ea * c0 + mb * ea * c1 + ma * eb * c2 + mb * eb * c3
        out[f] = val
        dm[f] = gm / hm
        dv[f] = gv / hv


@njit(cache=True)
def _objective(herm, xm, xv, k0, w, count, y, m, v, r, jm, jv, basis):
    surface(herm, xm, xv, k0, w, count, m, v, r, jm, jv, basis)
    total = 0.0
    for f in range(y.size):
        r[f] = (r[f] - y[f]) / y[f]
        jm[f] /= y[f]
        jv[f] /= y[f]
        total += r[f] * r[f]
    return total


@njit(cache=True)
def _gauss_newton(herm, xm, xv, k0, w, count, y, m, v, box):
    """Levenberg-Marquardt on eq. (7) from (m, v), kept inside ``box`` = (m_lo, m_hi, v_lo, v_hi)."""
    nf = y.size
    r = np.empty(nf)
    jm = np.empty(nf)
    jv = np.empty(nf)
    basis = np.empty((4, 4))
    sm = box[1] - box[0]
    sv = box[3] - box[2]
    lam = 1e-6
    cost = _objective(herm, xm, xv, k0, w, count, y, m, v, r, jm, jv, basis)
    for _ in range(60):
        a11 = a12 = a22 = g1 = g2 = 0.0
        for f in range(nf):  # scaled variables m/sm, v/sv
            p = jm[f] * sm
            q = jv[f] * sv
            a11 += p * p
            a12 += p * q
            a22 += q * q
            g1 += p * r[f]
            g2 += q * r[f]
        moved = False
        if cost < 1e-30:
            break
        for _try in range(8):
            b11 = a11 * (1 + lam) + 1e-300
            b22 = a22 * (1 + lam) + 1e-300
            det = b11 * b22 - a12 * a12
            if det <= 0:
                lam *= 10.0
                continue
            dm = -(b22 * g1 - a12 * g2) / det * sm
            dv = -(b11 * g2 - a12 * g1) / det * sv
            if abs(dm) / sm + abs(dv) / sv < 1e-10 and lam < 1e-3:
                break  # converged: the Gauss-Newton step is below the resolution that matters
            mn = min(max(m + dm, box[0]), box[1])
            vn = min(max(v + dv, box[2]), box[3])
            new = _objective(herm, xm, xv, k0, w, count, y, mn, vn, r, jm, jv, basis)
            if new <= cost:
                step = abs(mn - m) / sm + abs(vn - v) / sv
                m, v, cost = mn, vn, new
                lam = max(lam * 0.1, 1e-12)
                moved = step > 1e-10
                break
            lam *= 10.0
        if not moved:
            break
    return m, v, cost


@njit(cache=True)
def fast_search(herm, xm, xv, coarse, cm, cv, pressures, p, y, extension):
    """Continuous minimum of eq. (7): (mass [kg], velocity [m/s], residual)."""
    k0, w, count = pressure_weights(pressures, p)
    nf = y.size
    n1, n2 = cm.size, cv.size
    costs = np.empty(n1 * n2)
    for a in range(n1):
        for b in range(n2):
            total = 0.0
            for f in range(nf):
                value = 0.0
                for q in range(count):
                    value += w[q] * coarse[f, k0 + q, a, b]
                d = (value - y[f]) / y[f]
                total += d * d
            costs[a * n2 + b] = total
    order = np.empty(STARTS, dtype=np.int64)
    start_cost = np.empty(STARTS)
    for s in range(STARTS):  # the STARTS best coarse nodes
        k = 0
        for c in range(1, costs.size):
            if costs[c] < costs[k]:
                k = c
        order[s] = k
        start_cost[s] = costs[k]
        costs[k] = np.inf
    sm = xm[-1] - xm[0]
    sv = xv[-1] - xv[0]
    box = np.array([xm[0] - extension * sm, xm[-1] + extension * sm, xv[0] - extension * sv,
                    xv[-1] + extension * sv])
    best_m, best_v, best = 0.0, 0.0, np.inf
    for s in range(min(STARTS, order.size)):
        if s > 0 and (best < 1e-20 or start_cost[s] > 1e3 * best):
            break  # an exact fit, or one far better than this node promises: no other basin competes
        a = order[s] // n2
        b = order[s] % n2
        m, v, cost = _gauss_newton(herm, xm, xv, k0, w, count, y, cm[a], cv[b], box)
        if cost < best:
            best_m, best_v, best = m, v, cost
    return best_m, best_v, best


@njit(cache=True)
def locate(herm, xm, xv, coarse, cm, cv, pressures, p, y, inside_residual, extension):
    """Best fit inside the map; when its residual exceeds ``inside_residual``, the best fit up to ``extension``
    beyond the edges. Returns (mass [kg], velocity [m/s], residual, searched beyond the edges)."""
    m, v, cost = fast_search(herm, xm, xv, coarse, cm, cv, pressures, p, y, 0.0)
    if cost <= inside_residual:
        return m, v, cost, False
    m, v, cost = fast_search(herm, xm, xv, coarse, cm, cv, pressures, p, y, extension)
    return m, v, cost, True


def _subsample(axis: np.ndarray) -> np.ndarray:
    if axis.size <= FAST_NODES:
        return np.arange(axis.size)
    return np.unique(np.round(np.linspace(0, axis.size - 1, FAST_NODES)).astype(np.int64))


#: (herm, xm, xv, coarse, cm, cv, inside box (mass low, mass high, velocity low, velocity high))
FastTables = tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray,
                   tuple[float, float, float, float]]


def fast_tables(rmap: ResponseMap) -> FastTables:
    """(herm, xm, xv, coarse, cm, cv, inside box) of the fast search, computed once per map and cached on it."""
    cached = rmap._cache.get("fast")
    if cached is not None:
        return cached
    im, iv = _subsample(rmap.masses), _subsample(rmap.velocities)
    xm, xv = rmap.masses[im], rmap.velocities[iv]
    if xm.size < 2 or xv.size < 2:
        raise ResponseMapError(f"the fast search needs at least 2 masses and 2 velocities, got a {rmap.shape} map")
    dm, dv = spline_basis(xm, xm, 1), spline_basis(xv, xv, 1)
    nf, n_p = rmap.values.shape[:2]
    herm = np.empty((nf, n_p, xm.size, xv.size, 4))
    for f in range(nf):
        for p in range(n_p):
            y = rmap.values[f, p][np.ix_(im, iv)]
            herm[f, p, :, :, 0] = y
            herm[f, p, :, :, 1] = dm @ y
            herm[f, p, :, :, 2] = y @ dv.T
            herm[f, p, :, :, 3] = dm @ y @ dv.T
    cm = np.linspace(xm[0], xm[-1], COARSE)
    cv = np.linspace(xv[0], xv[-1], COARSE)
    coarse = np.empty((nf, n_p, COARSE, COARSE))
    out, gm, gv, basis = np.empty(nf), np.empty(nf), np.empty(nf), np.empty((4, 4))
    for p in range(n_p):
        w = np.zeros(4)
        w[0] = 1.0
        for a in range(COARSE):
            for b in range(COARSE):
                surface(herm, xm, xv, p, w, 1, cm[a], cv[b], out, gm, gv, basis)
                coarse[:, p, a, b] = out
    slack_m, slack_v = EDGE_TOLERANCE * (xm[-1] - xm[0]), EDGE_TOLERANCE * (xv[-1] - xv[0])
    inside = (float(xm[0] - slack_m), float(xm[-1] + slack_m), float(xv[0] - slack_v), float(xv[-1] + slack_v))
    tables = (np.ascontiguousarray(herm), xm.copy(), xv.copy(), coarse, cm, cv, inside)
    rmap._cache["fast"] = tables
    return tables


def brute_search(rmap: ResponseMap, y: np.ndarray, pressure_gauge: float) -> tuple[float, float, float, int, int]:
    """Eq. (7) at every node; (mass, velocity, residual, mass index, velocity index) of the minimum.

    Notes
    -----
    Implements eq. (7) of the reference paper, evaluated over the whole grid.
    """
    k0, w, count = pressure_weights(rmap.pressures_gauge, float(pressure_gauge))
    total: np.ndarray | None = None
    for f in range(y.size):
        layer = rmap.values[f, k0] if count == 1 and w[0] == 1.0 else \
            sum(w[q] * rmap.values[f, k0 + q] for q in range(count))
        d = (layer - y[f]) * (1.0 / y[f])
        d *= d
        total = d if total is None else total + d
    assert total is not None  # y holds at least one feature
    flat = int(np.argmin(total))
    i, j = divmod(flat, rmap.velocities.size)
    return float(rmap.masses[i]), float(rmap.velocities[j]), float(total.flat[flat]), i, j
