"""Geometrically exact planar Euler-Bernoulli beam: absolute nodal coordinates (ANCF).

This is the ``"corot"`` formulation of :mod:`sim.models.fe`: the big brother of FLXDYN's element,
exact for large rotations. Each node carries its position ``r`` and slope ``r' = dr/ds``
in the hub frame (4 dofs); the centre line is the cubic Hermite interpolation of them, so

- a rigid rotation is represented exactly (no small-rotation approximation anywhere),
- the position is linear in the coordinates, so the consistent mass matrix is constant and
  the rotating-frame inertia (centrifugal, Coriolis, Euler) is exact and linear,
- the strain energy is the exact one of an extensible elastica,
  ``U = 1/2 int EA (|r'| - 1)^2 + EI kappa^2 ds`` with ``kappa = (r' x r'') / |r'|^3``,
  integrated by Gauss quadrature; its gradient and Hessian are analytic.

Among the co-rotational, geometrically exact (rotation-based) and absolute-nodal choices
this one is the fastest at equal accuracy here: constant mass (no inertia recomputed per
step, the mass factorisation is done once), an exact tangent for the stiff integrator, and
no rotation parameters to update.

Dof order: node k (0 at the clamp) holds ``[x, y, x', y']`` at indices ``4k .. 4k+3``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from sim.beam import BeamProperties
from sim.checks import check_choice
from sim.config import DAMPING_LAWS

FloatArray = NDArray[np.float64]

N_GAUSS = 4  # bending: 4-point Gauss (exact for the linear part)
N_GAUSS_AXIAL = 2  # axial: reduced 2-point Gauss, against membrane locking
_CS_STEP = 1e-30  # complex step: no cancellation, so any tiny step is exact to rounding
_J2 = np.array([[0.0, -1.0], [1.0, 0.0]])  # rotation by +90 degrees (k x)


def hermite(xi: FloatArray, h: float) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Cubic Hermite shape functions at ``xi`` in [0, 1] on an element of length ``h``.

    Returns ``(n, dn_ds, d2n_ds2)``, each (len(xi), 4) for [value a, slope a, value b, slope b].
    """
    x = np.asarray(xi, dtype=float)
    n = np.stack(
        [
            1 - 3 * x**2 + 2 * x**3,
            h * (x - 2 * x**2 + x**3),
            3 * x**2 - 2 * x**3,
            h * (x**3 - x**2),
        ],
        axis=-1,
    )
    dn = np.stack(
        [(-6 * x + 6 * x**2) / h, 1 - 4 * x + 3 * x**2, (6 * x - 6 * x**2) / h, 3 * x**2 - 2 * x],
        axis=-1,
    )
    d2n = np.stack(
        [(-6 + 12 * x) / h**2, (-4 + 6 * x) / h, (6 - 12 * x) / h**2, (6 * x - 2) / h], axis=-1
    )
    return n, dn, d2n


def _energy_density_derivatives(
    g: FloatArray, hh: FloatArray, ea: FloatArray, ei: FloatArray, want_hessian: bool
) -> tuple[FloatArray, FloatArray | None]:
    """Gradient (..., 4) and Hessian (..., 4, 4) of the energy per unit length
    ``1/2 EA (|g| - 1)^2 + 1/2 EI (g x h)^2 / |g|^6`` with respect to ``(g, h)``."""
    g1, g2 = g[..., 0], g[..., 1]
    h1, h2 = hh[..., 0], hh[..., 1]
    n = g1 * g1 + g2 * g2
    ea = np.broadcast_to(ea, n.shape)
    ei = np.broadcast_to(ei, n.shape)
    sq = np.sqrt(n)
    c = g1 * h2 - g2 * h1
    n3 = 1.0 / (n * n * n)
    n4 = n3 / n
    ph = np.stack([h2, -h1], axis=-1)  # P h with c = g . P h
    ptg = np.stack([-g2, g1], axis=-1)  # P^T g with c = h . P^T g
    fa = ea * (1.0 - 1.0 / sq)
    b1 = ei * c * n3
    b2 = ei * c * c * n4
    grad = np.empty((*g.shape[:-1], 4))
    grad[..., 0:2] = fa[..., None] * g + b1[..., None] * ph - 3 * b2[..., None] * g
    grad[..., 2:4] = b1[..., None] * ptg
    if not want_hessian:
        return grad, None
    hess = np.empty((*g.shape[:-1], 4, 4))
    eye = np.eye(2)
    gg = g[..., :, None] * g[..., None, :]
    phg = ph[..., :, None] * g[..., None, :]
    e3 = (ei * n3)[..., None, None]
    hgg = (
        fa[..., None, None] * eye
        + (ea / (n * sq))[..., None, None] * gg
        + e3 * ph[..., :, None] * ph[..., None, :]
        - 6 * (b1 / n)[..., None, None] * (phg + np.swapaxes(phg, -1, -2))
        + 24 * (b2 / n)[..., None, None] * gg
        - 3 * b2[..., None, None] * eye
    )
    pmat = np.array([[0.0, 1.0], [-1.0, 0.0]])
    # d/dh of dU/dg: n^-3 (P h (P^T g)^T + c P) - 6 c n^-4 g (P^T g)^T
    hgh = (
        e3 * ph[..., :, None] * ptg[..., None, :]
        + b1[..., None, None] * pmat
        - 6 * (b1 / n)[..., None, None] * g[..., :, None] * ptg[..., None, :]
    )
    hhh = e3 * ptg[..., :, None] * ptg[..., None, :]
    hess[..., 0:2, 0:2] = hgg
    hess[..., 0:2, 2:4] = hgh
    hess[..., 2:4, 0:2] = np.swapaxes(hgh, -1, -2)
    hess[..., 2:4, 2:4] = hhh
    return grad, hess


def _bincount(idx: NDArray[np.intp], weights: FloatArray, minlength: int) -> FloatArray:
    return np.asarray(np.bincount(idx, weights=weights, minlength=minlength), dtype=float)


def _damped_force_fast(
    gh: FloatArray,
    dgh: FloatArray,
    ea: FloatArray,
    ei: FloatArray,
    a1: float,
    out: FloatArray | None = None,
) -> FloatArray:
    """Energy gradient plus ``a1`` times its rate along ``dgh``: (4, P, ...) each ->
    (4 P, ...). Pointwise and analytic, so it also takes complex arguments (complex-step
    derivatives).

    With ``g = r'``, ``h = r''``, ``n = |g|^2``, ``c = g x h``, ``b1 = EI c / n^3`` and
    ``k = EA (1 - n^-1/2) - 3 b1 c / n``, the gradient is ``(k g + b1 perp'(h), b1 perp(g))``
    with ``perp(x) = (-x2, x1)``, ``perp'(x) = (x2, -x1)``; its rate adds the same with
    ``k, b1`` replaced by their rates. The arrays are small, so the cost is the number of
    numpy operations (this runs at every Newton iteration): the fewest are written here,
    and callers in a hot loop pass 1-D components, (4, M), and ``ea``, ``ei`` of shape (M,)
    (a broadcast operation costs twice a plain one)."""
    g1, g2, h1, h2 = gh
    n = g1 * g1 + g2 * g2
    inv_n = 1.0 / n
    isq = np.sqrt(inv_n)
    c = g1 * h2 - g2 * h1
    e3 = ei * (inv_n * inv_n * inv_n)
    b1 = e3 * c
    b1n = b1 * inv_n
    k = ea * (1.0 - isq) - 3.0 * (b1n * c)  # not ea - ea isq: |r'| - 1 ~ 1e-6 cancels
    if a1 == 0.0:
        parts = [k * g1 + b1 * h2, k * g2 - b1 * h1, -b1 * g2, b1 * g1]
    else:
        d1, d2, e1, e2 = dgh
        gd = g1 * d1 + g2 * d2  # n' / 2
        dc = (d1 * h2 - d2 * h1) + (g1 * e2 - g2 * e1)
        q = c * gd * inv_n
        # b1' = EI (c' n^-3 - 3 c n' n^-4); (b1 c / n)' = b1 n^-1 (2 c' - 4 c n' / n)
        b1a = b1 + a1 * (e3 * (dc - 6.0 * q))
        ka = k + a1 * (ea * isq * inv_n * gd - 6.0 * b1n * (dc - 4.0 * q))
        kb = a1 * k
        b1b = a1 * b1
        parts = [
            ka * g1 + kb * d1 + (b1a * h2 + b1b * e2),
            ka * g2 + kb * d2 - (b1a * h1 + b1b * e1),
            -(b1a * g2 + b1b * d2),
            b1a * g1 + b1b * d1,
        ]
    if out is not None:  # (4, M) rows (the same numbers, written in place)
        out[0], out[1], out[2], out[3] = parts
        return out
    return np.concatenate(parts).reshape(4 * n.shape[0], *n.shape[1:])


def _material_damped_force(
    gh: Any, dgh: Any, ea: Any, ei: Any, a1: float
) -> Any:  # complex arrays too (complex-step derivatives)
    """Energy gradient plus ``a1`` times the material (strain-rate) part of its rate,
    ``a1 (EA eps' grad eps + EI kappa' grad kappa)``: Kelvin-Voigt damping, the
    ``"material"`` damping law; (4, P, ...) -> (4 P, ...)."""
    elastic = _damped_force_fast(gh, dgh, ea, ei, 0.0)
    if a1 == 0.0:
        return elastic
    g1, g2, h1, h2 = gh
    n = g1 * g1 + g2 * g2
    isq = 1.0 / np.sqrt(n)
    i3 = isq * isq * isq
    c = g1 * h2 - g2 * h1
    de = [g1 * isq, g2 * isq, 0.0 * g1, 0.0 * g1]  # grad eps, eps = |g| - 1
    dk = [  # grad kappa, kappa = c / |g|^3
        h2 * i3 - 3.0 * c * i3 * g1 / n,
        -h1 * i3 - 3.0 * c * i3 * g2 / n,
        -g2 * i3,
        g1 * i3,
    ]
    eps_rate = sum(a * b for a, b in zip(de, dgh, strict=True))
    kap_rate = sum(a * b for a, b in zip(dk, dgh, strict=True))
    damp = np.stack([a1 * (ea * eps_rate * de[k] + ei * kap_rate * dk[k]) for k in range(4)])
    return elastic + damp.reshape(elastic.shape)


# The paper law's pointwise force and its exact derivatives (:func:`_paper_force_jacobian`).
# With n = |g|^2, c = g x h and the energy density W(n, c) = EA/2 (n^1/2 - 1)^2 + EI/2 c^2 / n^3,
# every derivative is a combination of four vectors of (g, h) and of the rates u = (g', h'):
# grad n = (2 g, 0), grad c = (perp'(h), perp(g)), and their rates' counterparts
# (Hess n) u = (2 g', 0), (Hess c) u = (perp'(h'), perp(g')); _VMAP makes all four, (4 x 4)
# per point, from [g, h, g', h'] in one product.
_VMAP = np.zeros((4, 4, 8))
_VMAP[0, 0, 0] = _VMAP[0, 1, 1] = 2.0
_VMAP[1, 0, 3], _VMAP[1, 1, 2], _VMAP[1, 2, 1], _VMAP[1, 3, 0] = 1.0, -1.0, -1.0, 1.0
_VMAP[2, 0, 4] = _VMAP[2, 1, 5] = 2.0
_VMAP[3, 0, 7], _VMAP[3, 1, 6], _VMAP[3, 2, 5], _VMAP[3, 3, 4] = 1.0, -1.0, -1.0, 1.0
_VMAP_T = np.ascontiguousarray(_VMAP.reshape(16, 8).T)  # (8, 16)
# the Jacobians' coefficient matrices G (J = V^T G V), laid out (vector k, by the
# coordinates or the rates, vector l), as linear maps of [W_nn, W_nc, W_cc, t1, t2, t3] (the
# t_i are the a1 terms): _GMAP the entries of weight 1, _GMAP_A1 those of weight a1
_GMAP = np.zeros((6, 4, 2, 4))
_GMAP_A1 = np.zeros((6, 4, 2, 4))
for (_i, _j), (_w, _t) in {(0, 0): (0, 3), (0, 1): (1, 4), (1, 0): (1, 4), (1, 1): (2, 5)}.items():
    _GMAP[_w, _i, 0, _j] = _GMAP[_t, _i, 0, _j] = 1.0
    _GMAP_A1[_w, _i, 1, _j] = 1.0  # by the rates: a1 Hess W
for _w, (_i, _j) in ((0, (0, 2)), (1, (0, 3)), (1, (1, 2)), (2, (1, 3))):
    _GMAP_A1[_w, _i, 0, _j] = _GMAP_A1[_w, _j, 0, _i] = 1.0
# the constant Hessians of n (2 diag(1, 1, 0, 0)) and c, weighted by [alpha, beta] (by the
# coordinates) and [a1 W_n, a1 W_c] (by the rates); laid out (out, coordinates / rates, in)
_CMAP4 = np.zeros((4, 4, 2, 4))
for _b, _w in ((0, 0), (1, 2)):
    _CMAP4[_w, 0, _b, 0] = _CMAP4[_w, 1, _b, 1] = 2.0
    _CMAP4[_w + 1, 0, _b, 3] = _CMAP4[_w + 1, 3, _b, 0] = 1.0
    _CMAP4[_w + 1, 1, _b, 2] = _CMAP4[_w + 1, 2, _b, 1] = -1.0
_CMAP = _CMAP4.reshape(4, 32)


def paper_gmap(a1: float) -> FloatArray:
    """:func:`_paper_force_jacobian`'s coefficient map for the damping ``a1``, (6, 32)."""
    return np.asarray((_GMAP + a1 * _GMAP_A1).reshape(6, 32), dtype=np.float64)


def _paper_force_jacobian(
    x8: FloatArray, ea: FloatArray, ei: FloatArray, a1: float, gmap: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """The paper law's pointwise force ``grad W + a1 (Hess W) u`` and its exact Jacobian,
    in closed form: ``x8`` (8, M) rows ``[g, h, u]`` (``u`` the rates of ``g, h``), ``ea``
    (2, M) rows ``EA / 2``, ``EA / 4`` (exact scalings), ``ei`` (M,) and
    :func:`paper_gmap` ``(a1)`` -> force (M, 4) and Jacobians (M, 4 out, 8 in), by
    ``(g, h)`` then by ``u``.

    With ``V`` the four vectors of ``_VMAP``, ``N = grad n . u``, ``C = grad c . u``:
    ``f = V^T [alpha, beta, a1 W_n, a1 W_c]`` (``alpha = W_n + a1 (W_nn N + W_nc C)``,
    ``beta = W_c + a1 (W_nc N + W_cc C)``); ``df/d(g, h) = V^T G V + alpha Hess n + beta
    Hess c`` with the symmetric ``G = [[W_nn + t1, W_nc + t2, a1 W_nn, a1 W_nc], [W_nc + t2,
    W_cc + t3, a1 W_nc, a1 W_cc], [a1 W_nn, a1 W_nc, 0, 0], [a1 W_nc, a1 W_cc, 0, 0]]``
    (``t1 = a1 (W_nnn N + W_nnc C)``, ``t2 = a1 (W_nnc N + W_ncc C)``, ``t3 = a1 W_ncc N``:
    the third derivatives along ``u``); ``df/du = a1 Hess W``. The arrays are small, so the
    cost is the number of numpy calls: about forty here, against eight complex force
    evaluations for complex-step derivatives."""
    g1, g2, h1, h2, d1, d2, e1, e2 = x8
    m = g1.size
    # coef (6, M): W_nn, W_nc, W_cc, t1, t2, t3; weights (4, M): alpha, beta, a1 W_n, a1 W_c;
    # each row is its last operation's output (no packing afterwards)
    buf = np.empty((10, m))
    coef, weights = buf[:6], buf[6:]
    inv_n = 1.0 / (g1 * g1 + g2 * g2)
    isq = np.sqrt(inv_n)
    c = g1 * h2 - g2 * h1
    e3 = np.multiply(ei, inv_n * inv_n * inv_n, out=coef[2])  # EI n^-3 = W_cc
    ci = c * inv_n
    e3ci = e3 * ci  # EI c n^-4
    ea4 = ea[1] * (isq * inv_n)  # EA n^-3/2 / 4
    w_n = ea[0] * (1.0 - isq) - (e3ci * c) * 1.5  # not ea - ea isq: |g| - 1 ~ 1e-6
    w_c = e3 * c
    w_nn = np.add(ea4, (e3ci * ci) * 6.0, out=coef[0])
    w_nc = np.multiply(e3ci, -3.0, out=coef[1])
    w_ncc = (e3 * inv_n) * -3.0
    w_nnc = (w_nc * inv_n) * -4.0
    w_nnn = (ea4 * inv_n) * -1.5 - (e3ci * ci * inv_n) * 30.0
    a1n = (g1 * d1 + g2 * d2) * (2.0 * a1)  # a1 N
    a1c = ((d1 * h2 - d2 * h1) + (g1 * e2 - g2 * e1)) * a1  # a1 C
    np.add(w_nnn * a1n, w_nnc * a1c, out=coef[3])
    np.add(w_nnc * a1n, w_ncc * a1c, out=coef[4])
    np.multiply(w_ncc, a1n, out=coef[5])
    np.add(w_n, w_nn * a1n + w_nc * a1c, out=weights[0])
    np.add(w_c, w_nc * a1n + e3 * a1c, out=weights[1])
    np.multiply(w_n, a1, out=weights[2])
    np.multiply(w_c, a1, out=weights[3])
    v = (x8.T @ _VMAP_T).reshape(m, 4, 4)  # (M, vector, component)
    vt = v.transpose(0, 2, 1)
    force = (vt @ weights.T[:, :, None])[..., 0]  # (M, 4)
    gv = (coef.T @ gmap).reshape(m, 8, 4) @ v  # (M, (vector, coordinates / rates), in)
    jac = vt @ gv.reshape(m, 4, 8)
    jac += (weights.T @ _CMAP).reshape(m, 4, 8)
    return force, jac


@dataclass
class AncfBeam:
    """A uniform beam of ``n_elements`` ANCF elements clamped at ``(hub_offset, 0)``, axis +x."""

    beam: BeamProperties
    n_elements: int
    axial_points: int = N_GAUSS_AXIAL
    h: float = field(init=False)
    n_dof: int = field(init=False)
    free: NDArray[np.intp] = field(init=False)
    e_ref: FloatArray = field(init=False)
    mass: FloatArray = field(init=False)
    mass_j: FloatArray = field(init=False)

    def __post_init__(self) -> None:
        ne = self.n_elements
        self.h = self.beam.length_m / ne
        self.n_dof = 4 * (ne + 1)
        self.free = np.arange(4, self.n_dof)
        s_nodes = np.linspace(0.0, self.beam.length_m, ne + 1)
        e = np.zeros((ne + 1, 4))
        e[:, 0] = self.beam.hub_offset_m + s_nodes
        e[:, 2] = 1.0
        self.e_ref = e.ravel()
        # one point set: bending points (axial weight 0), then axial points (bending weight 0);
        # the weights are folded into per-point stiffnesses
        xb, wb = np.polynomial.legendre.leggauss(N_GAUSS)
        xa, wa = np.polynomial.legendre.leggauss(self.axial_points)
        xi = 0.5 * (np.concatenate([xb, xa]) + 1.0)
        nb = N_GAUSS
        self.ea_q = np.zeros(xi.size)
        self.ei_q = np.zeros(xi.size)
        self.ei_q[:nb] = 0.5 * wb * self.h * self.beam.bending_stiffness_n_m2
        self.ea_q[nb:] = 0.5 * wa * self.h * self.beam.axial_stiffness_n
        self.wq = np.ones(xi.size)
        _, self.dn, self.d2n = hermite(xi, self.h)
        # element dof indices (ne, 8) in the order [node a: x y x' y', node b: ...]
        self.edofs = 4 * np.arange(ne)[:, None] + np.arange(8)[None, :]
        # scalar Hermite consistent mass, then expand to 2-D with identity / J2
        x5, w5 = np.polynomial.legendre.leggauss(6)
        n5, _, _ = hermite(0.5 * (x5 + 1.0), self.h)
        m_s = self.beam.mass_per_length_kg_m * np.einsum("q,qi,qj->ij", 0.5 * w5 * self.h, n5, n5)
        self.mass = self._assemble_scalar(m_s, np.eye(2))
        self.mass_j = self._assemble_scalar(m_s, _J2)
        # B matrices: map element dofs (8) to (g, h) at each Gauss point: (nq, 4, 8)
        b = np.zeros((xi.size, 4, 8))
        for k in range(4):
            for d in range(2):
                b[:, d, 2 * k + d] = self.dn[:, k]
                b[:, 2 + d, 2 * k + d] = self.d2n[:, k]
        self.bmat = b
        # global maps from all coordinates to (g1, g2, h1, h2) at every point: (4, P, n_dof)
        npt = ne * xi.size
        bg = np.zeros((4, npt, self.n_dof))
        for el in range(ne):
            sl = slice(el * xi.size, (el + 1) * xi.size)
            for comp in range(4):
                bg[comp, sl, 4 * el : 4 * el + 8] = b[:, comp, :]
        self.bglob = bg
        self.ea_p = np.tile(self.ea_q, ne)
        self.ei_p = np.tile(self.ei_q, ne)
        rows = np.broadcast_to(self.edofs[:, :, None], (ne, 8, 8))
        cols = np.broadcast_to(self.edofs[:, None, :], (ne, 8, 8))
        self._flat_kidx = (rows * self.n_dof + cols).ravel()

    def _assemble_scalar(self, m_s: FloatArray, block: FloatArray) -> FloatArray:
        out = np.zeros((self.n_dof, self.n_dof))
        for e in range(self.n_elements):
            idx = self.edofs[e]
            out[np.ix_(idx, idx)] += np.kron(m_s, block)
        return out

    # -- strain measures ---------------------------------------------------------------
    def _gh(self, e_full: FloatArray) -> tuple[FloatArray, FloatArray]:
        ee = e_full[self.edofs].reshape(self.n_elements, 4, 2)
        g = np.einsum("qk,ekd->eqd", self.dn, ee)
        hh = np.einsum("qk,ekd->eqd", self.d2n, ee)
        return g, hh

    def internal_force(self, e_full: FloatArray) -> FloatArray:
        """Gradient of the strain energy (n_dof,)."""
        g, hh = self._gh(e_full)
        grad, _ = _energy_density_derivatives(g, hh, self.ea_q, self.ei_q, False)
        fe = np.einsum("q,eqi,qij->ej", self.wq, grad, self.bmat)
        return _bincount(self.edofs.ravel(), weights=fe.ravel(), minlength=self.n_dof)

    def force_and_rate(
        self, e_full: FloatArray, v_full: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """Internal force and its rate ``K_T(e) v`` (both (n_dof,))."""
        g, hh = self._gh(e_full)
        grad, hess = _energy_density_derivatives(g, hh, self.ea_q, self.ei_q, True)
        assert hess is not None
        vv = v_full[self.edofs]  # (ne, 8)
        dgh = np.einsum("qij,ej->eqi", self.bmat, vv)
        dgrad = np.einsum("eqij,eqj->eqi", hess, dgh)
        both = np.einsum("q,beqi,qij->bej", self.wq, np.stack([grad, dgrad]), self.bmat)
        idx = self.edofs.ravel()
        f = _bincount(idx, weights=both[0].ravel(), minlength=self.n_dof)
        kv = _bincount(idx, weights=both[1].ravel(), minlength=self.n_dof)
        return f, kv

    def tangent(self, e_full: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Internal force (n_dof,) and tangent stiffness K_T (n_dof, n_dof)."""
        g, hh = self._gh(e_full)
        grad, hess = _energy_density_derivatives(g, hh, self.ea_q, self.ei_q, True)
        assert hess is not None
        fe = np.einsum("q,eqi,qij->ej", self.wq, grad, self.bmat)
        ke = np.einsum("q,qai,eqab,qbj->eij", self.wq, self.bmat, hess, self.bmat)
        idx = self.edofs.ravel()
        f = _bincount(idx, weights=fe.ravel(), minlength=self.n_dof)
        k = _bincount(self._flat_kidx, weights=ke.ravel(), minlength=self.n_dof**2)
        return f, k.reshape(self.n_dof, self.n_dof)

    def strain_energy(self, e_full: FloatArray) -> float:
        g, hh = self._gh(e_full)
        n = np.sum(g * g, axis=-1)
        c = g[..., 0] * hh[..., 1] - g[..., 1] * hh[..., 0]
        dens = 0.5 * self.ea_q * (np.sqrt(n) - 1.0) ** 2 + 0.5 * self.ei_q * c * c / n**3
        return float(np.sum(dens))

    # -- sampling along the beam --------------------------------------------------------
    def _locate(self, s_m: FloatArray) -> tuple[NDArray[np.intp], FloatArray]:
        s = np.asarray(s_m, dtype=float)
        el = np.clip((s / self.h).astype(np.intp), 0, self.n_elements - 1)
        xi = s / self.h - el
        return el, xi

    def sample(self, e_hist: FloatArray, s_m: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Positions ``r`` and slopes/curvatures at arc lengths ``s_m``.

        Parameters
        ----------
        e_hist : (T, n_dof) full coordinate histories.
        s_m : (S,) arc lengths from the clamp.

        Returns
        -------
        r : (T, S, 2) hub-frame positions.
        strain_pair : (T, S, 2) axial strain and curvature ``kappa`` (1/m). The axial strain
            is the element's mean of ``|r'| - 1`` over its (reduced) axial Gauss points: the
            assumed constant strain the energy uses; pointwise ``|r'| - 1`` of a cubic
            centre line oscillates (the membrane-locking mode the reduced rule releases).
        """
        el, xi = self._locate(s_m)
        n, dn, d2n = hermite(xi, self.h)
        ee = e_hist[:, self.edofs[el]].reshape(e_hist.shape[0], len(el), 4, 2)
        r = np.einsum("sk,tskd->tsd", n, ee)
        g = np.einsum("sk,tskd->tsd", dn, ee)
        hh = np.einsum("sk,tskd->tsd", d2n, ee)
        nn = np.sqrt(np.sum(g * g, axis=-1))
        kappa = (g[..., 0] * hh[..., 1] - g[..., 1] * hh[..., 0]) / nn**3
        xa, _ = np.polynomial.legendre.leggauss(self.axial_points)
        _, dna, _ = hermite(0.5 * (xa + 1.0), self.h)
        ga = np.einsum("ak,tskd->tsad", dna, ee)
        eps = np.mean(np.sqrt(np.sum(ga * ga, axis=-1)), axis=-1) - 1.0
        return r, np.stack([eps, kappa], axis=-1)


class AncfSystem:
    """Equations of motion in the rotating hub frame for the unconstrained coordinates.

    State ``y = [d, v]``: ``d`` the displacement of the free coordinates from the straight,
    unstrained beam, ``v = dd/dt``. With the hub angle prescribed (Eqs. 35-36: only the
    unprescribed coordinates are solved for) and the constant mass matrix,

    ``M a + (2 Omega M_J + a0 M + a1 K_T) v + f(e) + alpha M_J e - Omega^2 M e = 0``

    where ``M_J = int rhoA S^T J S`` carries the Coriolis and Euler terms, ``-Omega^2 M e``
    the centrifugal load. Damping acts on ``v``, the rates relative to the hub frame, so a
    beam moving rigidly with the hub feels none.

    ``damping_law`` chooses the ``a1`` term: ``"paper"`` (default) is Eq. 28's ``a1 K_T v``
    with the full tangent stiffness; ``"material"`` is Kelvin-Voigt (strain-rate) damping,
    ``a1 K_mat v = a1 int (EA eps' grad eps + EI kappa' grad kappa)``, the law of Exudyn's
    ANCF cable. The two differ by the geometric part ``a1 (N d2eps + M d2kappa) v``: a force
    from the current axial force and bending moment times the rotation rate of the centre
    line relative to the hub, which is not a strain rate. ``a0 M v`` is the same in both.

    ``fused`` (default): with the paper law and ``a1 > 0``, :meth:`rhs_stages` and
    :meth:`rhs_jac_stages` take the fused path (closed-form pointwise Jacobians, one
    product for the accelerations); ``False`` keeps the complex-step path. Both agree to
    rounding, but an adaptive step control turns rounding into changes of the size of its
    tolerance (a step more or less), so :func:`sim.models.fe.simulate_fe` fuses only at a
    fixed step, and its adaptive runs stay bit for bit what they were.
    """

    def __init__(
        self,
        beam: BeamProperties,
        n_elements: int,
        drive: object,
        a0: float,
        a1: float,
        damping_law: str = "paper",
        fused: bool = True,
    ) -> None:
        self.damping_law = check_choice("damping_law", damping_law, DAMPING_LAWS)
        self.fe = AncfBeam(beam, n_elements)
        self.drive = drive
        self.a0 = a0
        self.a1 = a1
        fr = self.fe.free
        self.nf = fr.size
        m_ff = self.fe.mass[np.ix_(fr, fr)]
        self.minv = np.linalg.inv(m_ff)
        self.minv_m = self.minv @ self.fe.mass[fr, :]  # (nf, n_dof)
        self.minv_mj = self.minv @ self.fe.mass_j[fr, :]
        self.minv_mj_ff = self.minv_mj[:, fr]
        self.n_state = 2 * self.nf
        fe = self.fe
        self.bf = fe.bglob[:, :, fr]  # (4, P, nf)
        self.gh0 = fe.bglob @ fe.e_ref  # (4, P)
        npt = self.bf.shape[1]
        self.bf_flat = self.bf.reshape(4 * npt, self.nf)
        self.minv_bt = self.minv @ self.bf_flat.T  # (nf, 4P)
        self.m_e0 = self.minv_m @ fe.e_ref
        self.mj_e0 = self.minv_mj @ fe.e_ref
        self.m_ff = self.minv_m[:, fr]
        # the same maps ordered point by point: B per point (P, 4, nf), M^-1 B^T (nf, P 4)
        self.b_pts = np.ascontiguousarray(self.bf.transpose(1, 0, 2))
        self.minv_bt_pts = np.ascontiguousarray(
            self.minv_bt.reshape(self.nf, 4, npt).transpose(0, 2, 1).reshape(self.nf, -1)
        )
        self.eye = np.eye(self.nf)
        # the right-hand side's rotating-frame terms as one product with [d; v] (2 nf, k):
        # rows [M^-1 M_ff d; M^-1 M_J d; M^-1 M_J v] weighted by (Omega^2, -alpha, -2 Omega),
        # plus the constant loads, minus a0 v
        nf = self.nf
        zero = np.zeros((nf, nf))
        self._frame_map = np.block(
            [[self.m_ff, zero], [self.minv_mj_ff, zero], [zero, self.minv_mj_ff]]
        ).reshape(3, nf, 2 * nf)
        self._frame_load = np.stack([self.m_e0, self.mj_e0, np.zeros(nf)])[:, :, None]
        # the acceleration rows' constant and frame parts of the Jacobian, (nf, 2 nf) each,
        # weighted by (1, Omega^2, -alpha, -2 Omega)
        self._jac_frame = np.stack(
            [
                np.hstack([zero, -self.a0 * self.eye]),
                np.hstack([self.m_ff, zero]),
                np.hstack([self.minv_mj_ff, zero]),
                np.hstack([zero, self.minv_mj_ff]),
            ]
        ).reshape(4, -1)
        # tangent assembly, element by element: K_e = sum_q B_q^T D_q B_q is one product of
        # the pointwise derivatives (rows: batch, element; columns: q, out, in) with
        # W[(q, a, b), (i, j)] = B[q, a, i] B[q, b, j] (the mesh is uniform), then a scatter
        # of the blocks' free-free entries into K (nf, nf)
        nq = fe.bmat.shape[0]
        self._nq = nq
        self._w_tangent = np.einsum("qai,qbj->qabij", fe.bmat, fe.bmat).reshape(nq * 16, 64)
        rows = np.broadcast_to(fe.edofs[:, :, None], (fe.n_elements, 8, 8)).ravel()
        cols = np.broadcast_to(fe.edofs[:, None, :], (fe.n_elements, 8, 8)).ravel()
        first = int(fr[0])
        self._keep = (rows >= first) & (cols >= first)
        self._target = ((rows - first) * self.nf + (cols - first))[self._keep]
        self._scatter: dict[int, NDArray[np.intp]] = {}
        # one-hot imaginary perturbations for the complex-step derivatives: component k of
        # gh in column k, of dgh (with damping) in column 4 + k
        npert = 8 if a1 != 0.0 else 4
        self._perturbation = np.zeros((2, 4, npert), dtype=complex)
        self._perturbation[0, :, :4] = 1j * _CS_STEP * np.eye(4)
        if npert == 8:
            self._perturbation[1, :, 4:] = 1j * _CS_STEP * np.eye(4)
        self._stiffness: dict[tuple[int, ...], tuple[FloatArray, FloatArray]] = {}
        self._gmap = paper_gmap(a1)
        # the damped paper law (the reciprocating scene's) evaluates fused: [g, h, g', h'] at
        # every point from the states in one product, the accelerations from
        # [d; v; force; 1] in one product weighted by (1, Omega^2, -alpha, -2 Omega); the
        # arrays are small, so the number of numpy calls is the cost
        self._fused = fused and self.damping_law == "paper" and a1 != 0.0
        npt4 = 4 * npt
        self._x8_map = np.zeros((2 * npt4, 2 * nf))
        self._x8_map[:npt4, :nf] = self.bf_flat
        self._x8_map[npt4:, nf:] = self.bf_flat
        self._x8_0 = np.concatenate([self.gh0.reshape(-1), np.zeros(npt4)])[:, None]
        acc_map = np.zeros((4, nf, 2 * nf + npt4 + 1))
        acc_map[0, :, nf : 2 * nf] = -self.a0 * self.eye
        acc_map[0, :, 2 * nf : 2 * nf + npt4] = -self.minv_bt
        acc_map[1, :, :nf], acc_map[1, :, -1] = self.m_ff, self.m_e0
        acc_map[2, :, :nf], acc_map[2, :, -1] = self.minv_mj_ff, self.mj_e0
        acc_map[3, :, nf : 2 * nf] = self.minv_mj_ff
        self._acc_map = acc_map.reshape(4 * nf, -1)
        self._hub_cache: dict[bytes, FloatArray] = {}
        self._ea_halves: dict[int, FloatArray] = {}
        self._jac_template: dict[int, FloatArray] = {}

    def full(self, d: FloatArray) -> FloatArray:
        e = self.fe.e_ref.copy()
        e[self.fe.free] += d
        return e

    def full_rate(self, v: FloatArray) -> FloatArray:
        out = np.zeros(self.fe.n_dof)
        out[self.fe.free] = v
        return out

    def _hub(self, t: float) -> tuple[float, float]:
        om = float(self.drive.rate(t))  # type: ignore[attr-defined]
        al = float(self.drive.accel(t))  # type: ignore[attr-defined]
        return om, al

    def _gh(self, d: FloatArray) -> FloatArray:
        return self.gh0 + self.bf @ d

    def _force(self, gh: Any, dgh: Any, extra_axes: int) -> Any:
        """Generalized internal force at the Gauss points (elastic + the damping law's
        ``a1`` rate term), real or complex; ``gh``, ``dgh`` are (4, P) followed by
        ``extra_axes`` axes. The damping law acts here and only here."""
        if self.damping_law == "material":
            axes = (slice(None),) + (None,) * extra_axes
            return _material_damped_force(gh, dgh, self.fe.ea_p[axes], self.fe.ei_p[axes], self.a1)
        shape = gh.shape[1:]
        stiff = self._stiffness.get(shape)
        if stiff is None:  # per-point EA, EI spread over the extra axes, flattened
            ea, ei = (
                np.ascontiguousarray(
                    np.broadcast_to(x.reshape(-1, *(1,) * extra_axes), shape)
                ).ravel()
                for x in (self.fe.ea_p, self.fe.ei_p)
            )
            stiff = (ea, ei)
            self._stiffness[shape] = stiff
        flat = _damped_force_fast(
            gh.reshape(4, -1), dgh.reshape(4, -1), stiff[0], stiff[1], self.a1
        )
        return flat.reshape(4 * shape[0], *shape[1:])

    def rhs(self, t: float, y: FloatArray) -> FloatArray:
        nf = self.nf
        d, v = y[:nf], y[nf:]
        om, al = self._hub(t)
        gh = self._gh(d)
        dgh = self.bf @ v if self.a1 != 0.0 else gh
        gen = self._force(gh, dgh, 0)
        acc = (
            -self.minv_bt @ gen
            - 2.0 * om * (self.minv_mj_ff @ v)
            - al * (self.mj_e0 + self.minv_mj_ff @ d)
            + om * om * (self.m_e0 + self.m_ff @ d)
            - self.a0 * v
        )
        return np.concatenate([v, acc])

    def _stage_terms(
        self, ts: FloatArray, ys: FloatArray
    ) -> tuple[FloatArray, FloatArray, FloatArray, FloatArray, FloatArray, FloatArray]:
        """Hub rate and acceleration (k,), coordinates and rates (nf, k), and ``gh``,
        ``dgh`` (4, P, k) at the Gauss points."""
        nf = self.nf
        d, v = ys[:, :nf].T, ys[:, nf:].T  # (nf, k)
        om = np.asarray(self.drive.rate(ts), dtype=np.float64)  # type: ignore[attr-defined]
        al = np.asarray(self.drive.accel(ts), dtype=np.float64)  # type: ignore[attr-defined]
        gh = self.gh0[..., None] + self.bf @ d  # (4, P, k)
        dgh = self.bf @ v if self.a1 != 0.0 else gh
        return om, al, d, v, gh, dgh

    def _rhs_from_force(
        self, om: FloatArray, al: FloatArray, d: FloatArray, v: FloatArray, gen: FloatArray
    ) -> FloatArray:
        """(k, n_state) right-hand sides from the Gauss-point forces ``gen`` (4 P, k)."""
        frame = self._frame_map @ np.concatenate([d, v]) + self._frame_load  # (3, nf, k)
        acc = (
            om * om * frame[0] - al * frame[1] - (2.0 * om) * frame[2]
            - self.minv_bt @ gen - self.a0 * v
        )  # fmt: skip
        return np.concatenate([v, acc]).T

    def _hub_weights(self, ts: FloatArray) -> FloatArray:
        """(4, k) rows ``1, Omega^2, -alpha, -2 Omega`` at the times ``ts``, kept for the
        last few time sets (a Newton iteration evaluates its stages' times again; the key
        is the times' bytes, so a changed array is never mistaken). Read only."""
        key = ts.tobytes()
        w = self._hub_cache.get(key)
        if w is None:
            both = getattr(self.drive, "rate_accel", None)  # one call where the drive has it
            if both is not None:
                om, al = (np.asarray(x, dtype=np.float64) for x in both(ts))
            else:
                om = np.asarray(self.drive.rate(ts), dtype=np.float64)  # type: ignore[attr-defined]
                al = np.asarray(self.drive.accel(ts), dtype=np.float64)  # type: ignore[attr-defined]
            w = np.array([np.ones(ts.size), om * om, -al, -2.0 * om])
            if len(self._hub_cache) >= 4:
                self._hub_cache.clear()
            self._hub_cache[key] = w
        return w

    def _fused_points(self, ys: FloatArray) -> tuple[FloatArray, FloatArray, FloatArray]:
        """``[g, h, g', h']`` (8, P k) at every point and stage, and the points' EA, EI."""
        x8 = (self._x8_map @ ys.T + self._x8_0).reshape(8, -1)
        shape = (self.bf.shape[1], ys.shape[0])
        if shape not in self._stiffness:
            self._force(x8[:4].reshape(4, *shape), x8[4:].reshape(4, *shape), 1)  # caches
        ea, ei = self._stiffness[shape]
        return x8, ea, ei

    def _fused_ea(self, ea: FloatArray) -> FloatArray:
        """``[EA / 2, EA / 4]`` (2, M) for :func:`_paper_force_jacobian`, kept per size."""
        halves = self._ea_halves.get(ea.size)
        if halves is None:
            halves = self._ea_halves[ea.size] = np.array([0.5 * ea, 0.25 * ea])
        return halves

    def _fused_operand(self, ys: FloatArray) -> tuple[FloatArray, FloatArray]:
        """``[d; v; force; 1]`` (2 nf + 4 P + 1, k) with the force rows to be filled, and
        those rows as (4, P k), component by component."""
        k, n = ys.shape
        npt4 = 4 * self.bf.shape[1]
        x = np.empty((n + npt4 + 1, k))
        x[:n] = ys.T
        x[-1] = 1.0
        return x, x[n : n + npt4].reshape(4, -1)

    def _fused_rhs(self, w: FloatArray, ys: FloatArray, x: FloatArray) -> FloatArray:
        """(k, n_state) right-hand sides from :meth:`_fused_operand`'s ``x`` filled."""
        k, nf = ys.shape[0], self.nf
        acc = ((self._acc_map @ x).reshape(4, nf, k) * w[:, None, :]).sum(axis=0)
        return np.concatenate([ys[:, nf:], acc.T], axis=1)

    def rhs_stages(self, ts: FloatArray, ys: FloatArray) -> FloatArray:
        """The right-hand side at several points at once: (k,), (k, n_state) -> (k, n_state)."""
        if self._fused:
            w = self._hub_weights(ts)
            x8, ea, ei = self._fused_points(ys)
            x, force = self._fused_operand(ys)
            _damped_force_fast(x8[:4], x8[4:], ea, ei, self.a1, out=force)
            return self._fused_rhs(w, ys, x)
        om, al, d, v, gh, dgh = self._stage_terms(ts, ys)
        return self._rhs_from_force(om, al, d, v, self._force(gh, dgh, 1))

    def _force_derivatives(self, gh: FloatArray, dgh: FloatArray) -> tuple[FloatArray, FloatArray]:
        """The damped force (:meth:`_force`) and its pointwise derivatives by
        complex step: ``gh``, ``dgh`` (4, P, k) -> force (4 P, k) and derivatives
        (4, P, k, 4) w.r.t. ``gh``, then (with damping) (4, P, k, 4) w.r.t. ``dgh``,
        stacked on the last axis.

        The force at a Gauss point depends only on ``gh`` and ``dgh`` there, so eight
        (four without damping) complex evaluations give the exact tangent, third derivatives
        of the energy (the Kelvin-Voigt term's dependence on the state) included; their
        real part is the force itself (the perturbation is purely imaginary)."""
        npert = 8 if self.a1 != 0.0 else 4
        pert = self._perturbation
        extra = (None,) * (gh.ndim - 1)
        ghc = gh[..., None] + pert[0][(slice(None), *extra)]
        dghc = dgh[..., None] + pert[1][(slice(None), *extra)]
        f = self._force(ghc, dghc, 2)
        return f[..., 0].real, f.imag.reshape(4, *gh.shape[1:], npert) * (1.0 / _CS_STEP)

    def rhs_jac_stages(self, ts: FloatArray, ys: FloatArray) -> tuple[FloatArray, FloatArray]:
        """:meth:`rhs_stages` and :meth:`jac_stages` at the same points in one evaluation
        of the force: (k,), (k, n) -> (k, n), (k, n, n). The paper's law takes its
        pointwise derivatives in closed form (:func:`_paper_force_jacobian`), the material
        law and the undamped beam by complex step (:meth:`_force_derivatives`: four complex
        evaluations without damping cost less than the closed form); both are exact to
        rounding."""
        if not self._fused:
            return self._rhs_jac_stages_complex_step(ts, ys)
        nf = self.nf
        npts = ts.size
        w = self._hub_weights(ts)
        x8, ea, ei = self._fused_points(ys)
        force, local = _paper_force_jacobian(x8, self._fused_ea(ea), ei, self.a1, self._gmap)
        npt = self.bf.shape[1]
        # M^-1 sum_p B_p^T J_p B_p for every stage: J_p B_p per point, then one product
        # with M^-1 B^T over (point, component): kk (k, nf, 2 nf) is [M^-1 dF/dd, M^-1 dF/dv]
        jb = (local.reshape(npt, -1, 4) @ self.b_pts).reshape(npt, npts, 8 * nf)
        kk = self.minv_bt_pts @ jb.transpose(1, 0, 2).reshape(npts, npt * 4, 2 * nf)
        template = self._jac_template.get(npts)
        if template is None:
            template = np.zeros((npts, 2 * nf, 2 * nf))
            template[:, :nf, nf:] = self.eye
            self._jac_template[npts] = template
        jac = template.copy()
        jac[:, nf:, :] = (w.T @ self._jac_frame).reshape(npts, nf, 2 * nf) - kk
        x, force_rows = self._fused_operand(ys)
        np.copyto(force_rows, force.T)
        return self._fused_rhs(w, ys, x), jac

    def _rhs_jac_stages_complex_step(
        self, ts: FloatArray, ys: FloatArray
    ) -> tuple[FloatArray, FloatArray]:
        """:meth:`rhs_jac_stages` with complex-step pointwise derivatives (any law)."""
        nf = self.nf
        npts = ts.size
        om, al, d, v, gh, dgh = self._stage_terms(ts, ys)
        gen, local = self._force_derivatives(gh, dgh)  # (4P, k), (4 out, P, k, npert)
        ns = local.shape[-1] // 4  # derivatives w.r.t. gh, then (damped) w.r.t. dgh
        ne, nb = self.fe.n_elements, npts * ns
        dloc = local.reshape(4, ne, self._nq, npts, ns, 4).transpose(3, 4, 1, 2, 0, 5)
        k_el = (dloc.reshape(nb * ne, -1) @ self._w_tangent).reshape(nb, -1)[:, self._keep]
        idx = self._scatter.get(nb)
        if idx is None:
            idx = (np.arange(nb)[:, None] * (nf * nf) + self._target[None, :]).ravel()
            self._scatter[nb] = idx
        k_free = np.bincount(idx, weights=k_el.ravel(), minlength=nb * nf * nf)
        kk = self.minv @ k_free.reshape(npts, ns, nf, nf)  # M^-1 dF/d(d), M^-1 dF/d(v)
        jac = np.zeros((npts, 2 * nf, 2 * nf))
        jac[:, :nf, nf:] = self.eye
        weights = np.stack([np.ones(npts), om * om, -al, -2.0 * om], axis=1)  # (k, 4)
        acc = jac[:, nf:, :]
        acc[...] = (weights @ self._jac_frame).reshape(npts, nf, 2 * nf)
        acc[:, :, : ns * nf] -= kk.transpose(0, 2, 1, 3).reshape(npts, nf, ns * nf)
        return self._rhs_from_force(om, al, d, v, gen), jac

    def jac_stages(self, ts: FloatArray, ys: FloatArray) -> FloatArray:
        """Exact Jacobians of :meth:`rhs` at several points: (k,), (k, n) -> (k, n, n)."""
        return self.rhs_jac_stages(ts, ys)[1]

    def jac(self, t: float, y: FloatArray) -> FloatArray:
        """Exact Jacobian of :meth:`rhs` (n_state, n_state), by complex step: scipy's
        integrators (BDF, Radau: the references) call it a point at a time, where the
        closed form saves nothing, and their runs stay bit for bit what they were."""
        return self._rhs_jac_stages_complex_step(np.array([t]), y[None, :])[1][0]

    def initial_state(self) -> FloatArray:
        return np.zeros(self.n_state)

    def sample(self, y_hist: FloatArray, s_m: FloatArray) -> tuple[FloatArray, FloatArray]:
        """Hub-frame positions (T, S, 2) and [axial strain, curvature] (T, S, 2)."""
        e_hist = np.broadcast_to(self.fe.e_ref, (y_hist.shape[0], self.fe.n_dof)).copy()
        e_hist[:, self.fe.free] += y_hist[:, : self.nf]
        return self.fe.sample(e_hist, s_m)

    def energies(self, t: float, y: FloatArray) -> tuple[float, float, float]:
        """Kinetic energy in the inertial frame, strain energy and hub angular momentum
        (about the pivot) of the beam."""
        e = self.full(y[: self.nf])
        v = self.full_rate(y[self.nf :])
        om, _ = self._hub(t)
        m, mj = self.fe.mass, self.fe.mass_j
        # absolute velocity field S (v + Omega J e): T = 1/2 (v + om J e)^T M (v + om J e)
        kin = 0.5 * (v @ m @ v) - om * (e @ mj @ v) + 0.5 * om * om * (e @ m @ e)
        # angular momentum H = int rhoA r x (rdot + om J r) = -e^T M_J v + om e^T M e
        ang = -(e @ mj @ v) + om * (e @ m @ e)
        return float(kin), self.fe.strain_energy(e), float(ang)
