"""Nonlinear finite-element beams on a prescribed hub: dynamics and statics.

Two formulations, both planar Euler-Bernoulli with consistent mass, solved only for the
unprescribed (elastic) coordinates in the rotating hub frame (the partitioning of
Eqs. 35-36) with the exact centrifugal, Coriolis and Euler loads of the prescribed rotation:

- ``"flxdyn"`` (:mod:`sim.models.fe_flxdyn`): the paper's 6-dof element (Eqs. 29-33), each
  element's deformation in a frame attached to its inboard end, frames chained.
- ``"corot"`` (:mod:`sim.models.fe_ancf`): its big brother, exact for any rotation: absolute nodal
  coordinates with cubic Hermite interpolation and the exact elastica strain energy.

Proportional damping (Eq. 28), ``(a0 M + a1 K_T)`` times the elastic deformation rates,
never acts on the rigid motion of the hub; ``corot`` also has Kelvin-Voigt (strain-rate)
damping, ``damping_law="material"``, the law of Exudyn's cable. Integration: Radau IIA or
BDF with an exact Jacobian (scipy's, or for ``corot`` :mod:`sim.solvers.radau`: full Newton
with each stage's Jacobian, the fast one at moderate tolerances), so the axial modes and the
overdamped bending modes of the paper's damping (a1 = 0.1 s) cost little.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from typing import Any, Protocol

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sim.beam import BeamProperties
from sim.checks import (
    check_beam,
    check_choice,
    check_gauges,
    check_int,
    check_non_negative,
    check_positive,
    check_simulation_inputs,
)
from sim.config import DAMPING_LAWS
from sim.drives import Drive
from sim.errors import SimInputError, StaticSolveError
from sim.models.fe_ancf import AncfBeam, AncfSystem
from sim.models.fe_flxdyn import FlxdynBeam, FlxdynSystem
from sim.modes import mode_shapes
from sim.result import SimResult
from sim.solvers.integrate import integrate

FloatArray = NDArray[np.float64]

FORMULATIONS = ("corot", "flxdyn")


class _System(Protocol):
    n_state: int

    def rhs(self, t: float, y: FloatArray) -> FloatArray: ...

    def jac(self, t: float, y: FloatArray) -> FloatArray: ...

    def initial_state(self) -> FloatArray: ...

    def sample(self, y_hist: FloatArray, s_m: FloatArray) -> tuple[FloatArray, FloatArray]: ...


def _deflections(
    system: Any, y_hist: FloatArray, beam: BeamProperties, stations: FloatArray, gauges: FloatArray
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Station lateral/longitudinal deflections (T, S) and gauge strains (T, G)."""
    r, _ = system.sample(y_hist, stations)
    lat = r[..., 1]
    lon = r[..., 0] - (beam.hub_offset_m + stations)[None, :]
    if gauges.size:
        _, eps = system.sample(y_hist, gauges)
        strain = eps[..., 0] - beam.surface_offset_m * eps[..., 1]
    else:
        strain = np.zeros((y_hist.shape[0], 0))
    return lat, lon, strain


CURVATURES = ("element", "recovered")
#: both formulations' states are ``[coordinates, their rates]``: radau5 solves its Newton
#: iteration for the rates alone (half the unknowns, an eighth of the factorisation)
SECOND_ORDER = True
RECOVERY_MAX_MODES = 12


def recovered_curvature(
    system: AncfSystem, y_hist: FloatArray, gauges_m: FloatArray
) -> tuple[FloatArray, FloatArray]:
    """Curvature at the gauges recovered from the nodal values, and its error estimate.

    The element's own curvature (the second derivative of its cubic) converges only as h^2
    and jumps between elements: 4 % off at the 603 mm gauge with 3 elements on the paper's
    scene. The nodal positions and slopes converge as h^4 (like the tip), so the centre
    line is refitted through them: the lateral deflection w and the slope sin(theta) of
    the free nodes, in the hub frame, by least squares on m = min(2 n, 12) clamped-free
    modes (clamp conditions built in); the exact curvature is then
    kappa = w'' / sqrt(1 - w'^2) (w' = sin theta on the arc length).

    Returns
    -------
    kappa : (T, G) curvature at the gauges, 1/m.
    change : (T, G) the change of kappa from m - 1 to m modes: the fit's share of the
        error only (the nodal values' own error is not in it; on the paper's scene the real
        error was up to 3x the worst gauge's change, so :mod:`sim.models.model_choice`
        estimates from a second mesh instead).
    """
    fe = system.fe
    ne, length = fe.n_elements, fe.beam.length_m
    e = np.broadcast_to(fe.e_ref, (y_hist.shape[0], fe.n_dof)).copy()
    e[:, fe.free] += y_hist[:, : system.nf]
    nodes = e.reshape(e.shape[0], ne + 1, 4)[:, 1:, :]
    s_nodes = np.linspace(0.0, length, ne + 1)[1:]
    lateral = nodes[..., 1]
    sin_slope = nodes[..., 3] / np.hypot(nodes[..., 2], nodes[..., 3])
    data = np.concatenate([lateral, sin_slope], axis=1)  # (T, 2 ne)
    m = min(2 * ne, RECOVERY_MAX_MODES)
    out = []
    for k in (m - 1, m):
        basis = np.vstack([mode_shapes(s_nodes, length, k), mode_shapes(s_nodes, length, k, 1)])
        q = data @ np.linalg.pinv(basis).T
        slope = q @ mode_shapes(gauges_m, length, k, 1).T
        out.append(q @ mode_shapes(gauges_m, length, k, 2).T / np.sqrt(1.0 - slope**2))
    return out[1], np.abs(out[1] - out[0])


def _make_system(
    formulation: str,
    beam: BeamProperties,
    n_elements: int,
    drive: Drive,
    a0: float,
    a1: float,
    damping_law: str,
    fused: bool = False,
) -> _System:
    if formulation == "corot":
        return AncfSystem(beam, n_elements, drive, a0, a1, damping_law, fused)
    return FlxdynSystem(beam, n_elements, drive, a0, a1)


def simulate_fe(
    beam: BeamProperties,
    drive: Drive,
    t_eval_s: ArrayLike,
    *,
    n_elements: int = 4,
    formulation: str = "corot",
    a0_per_s: float = 0.0,
    a1_s: float = 0.0,
    gauge_positions_m: Sequence[float] | ArrayLike = (),
    n_stations: int = 21,
    rtol: float = 1e-6,
    atol: float = 1e-9,
    initial_state: ArrayLike | None = None,
    method: str = "auto",
    damping_law: str = "paper",
    curvature: str = "element",
    fixed_step_s: float | None = None,
    stages: int = 3,
    first_step_s: float | None = None,
) -> SimResult:
    """Simulate the beam clamped to a hub whose rotation ``drive`` prescribes.

    Parameters
    ----------
    beam : the beam; clamped at ``beam.hub_offset_m`` from the pivot, axis along the hub.
    drive : prescribed hub angle, rate and acceleration (``sim.drives.Drive``).
    t_eval_s : (N,) strictly increasing output times, s; the run starts at ``t_eval_s[0]``
        from ``initial_state`` (default: straight, unstrained, at rest relative to the hub).
    n_elements : number of beam elements (1 .. 200).
    formulation : ``"corot"`` (geometrically exact, absolute nodal coordinates) or
        ``"flxdyn"`` (the paper's element, Eqs. 29-33, chained local frames).
    a0_per_s, a1_s : proportional damping of Eq. 28 on the elastic deformation rates.
    gauge_positions_m : (G,) gauge distances from the clamp, m.
    n_stations : number of stations from clamp to tip (>= 2) for the shape output.
    rtol, atol : integrator tolerances (the state is displacements, m and rad-like slopes,
        and their rates).
    initial_state : (2 n,) state ``[coordinates, rates]`` of the unprescribed coordinates,
        e.g. ``result.settings["final_state"]`` of an earlier run with the same
        formulation and ``n_elements``.
    method : "auto" (default), "radau5", "BDF", "Radau" or "LSODA". "radau5" (``corot``
        only: it needs the stage Jacobians) is our Radau IIA with each stage's exact
        Jacobian at the predicted stages (:mod:`sim.solvers.radau`): the Kelvin-Voigt axial term
        a1 EA acts along the rotating centre line, so a Jacobian frozen over a step (scipy's
        Radau and BDF) makes Newton fail and the step collapse; with atol = rtol (1e-4 to
        1e-6) it is 8-10x faster than BDF at equal error on the paper's scene (what
        :mod:`sim.models.model_choice` and the speed table use). At tight
        tolerances with a tiny atol (references, rtol 1e-6 and below) it is slower, so
        "auto" stays with scipy: BDF when a1 > 0, Radau when ``a1_s == 0`` (undamped stiff
        axial modes make high-order BDF crawl: it is not A-stable).
    damping_law : the ``a1`` term: ``"paper"`` (default), Eq. 28's ``a1 K_T v``, or
        ``"material"`` (``corot`` only), Kelvin-Voigt strain-rate damping ``a1 K_mat v``,
        Exudyn's cable law (:class:`sim.models.fe_ancf.AncfSystem` says what differs).
    curvature : the gauges' curvature: ``"element"`` (default), the second derivative of
        the element's cubic (converges as h^2), or ``"recovered"`` (``corot`` only), refitted
        through the nodal values (:func:`recovered_curvature`, converges with the tip); then
        ``settings["curvature_fit_change"]`` holds the fit's change per gauge (relative
        to the gauge's largest strain; see :func:`recovered_curvature`).
    fixed_step_s : ``method="radau5"`` only: every step this long (the last one shortened),
        no error estimate or step control (``rtol``, ``atol`` then only scale Newton's
        stopping test), as Exudyn's fixed-step integrators; the error is not estimated, so
        it is for studies and benchmarks that measure it (``bench sim``; ``auto`` runs
        each mesh at h and h / 2, :mod:`sim.models.model_choice`). A step whose Newton
        iteration does not converge is taken in parts, down to 1/64 of it, then it raises
        (on the rig's beam and the paper's drive, steps above ~0.03 s do not converge: the
        axial stiffness EA turns the iterates' slope rotations into large spurious
        stretching forces; at 3 stages; a start from rest with the hub accelerating fails
        at shorter steps, see :func:`sim.solvers.radau.radau5`). At a fixed
        step ``corot`` with ``a1 > 0`` and the paper law evaluates fused (closed-form
        stage Jacobians, see :class:`sim.models.fe_ancf.AncfSystem`): 1.6x faster, the
        same answer to rounding (3e-11 of the tip on the paper's scene); adaptive runs
        keep the complex-step evaluation, bit for bit.
    first_step_s : with ``fixed_step_s`` only: the first step is taken in parts from this
        one, each twice the last (see :func:`sim.solvers.radau.radau5`).
    stages : with ``fixed_step_s`` (``corot``), the Radau IIA method's stages: 3 (default,
        order 5), 4 (order 7) or 5 (order 9). On the paper's damped scene the higher orders
        take longer steps at equal error, and their Newton iteration converges at longer
        steps (with Newton's test at 3e-5 or tighter: the stages' own iteration error
        spoils the next step's predictor at looser ones): 2 elements at 5 stages and 0.05 s
        (100 steps in 5 s) are 7.8e-5 of the tip from the converged answer, their spatial
        error alone, against 9.6e-5 at 3 stages and 0.03 s (167 steps; Newton does not
        converge at 0.04 s), and 8 elements 8.1e-7 in 100 steps, against 1.0e-6 in 400.
        Much longer steps can make Newton converge to a wrong solution of the collocation
        equations (5 stages at 0.083 s: 0.69 of the tip off): as for any fixed step, the
        error is not estimated, so measure it.

    Returns
    -------
    SimResult
        ``model`` is ``"fe-corot"`` or ``"fe-flxdyn"``; ``wall_time_s`` is the integration
        alone; ``settings`` holds formulation, n_elements, rtol, atol, damping, method,
        solver counts and ``final_state``.

    Raises
    ------
    sim.solvers.integrate.IntegrationError
        if the integrator fails (never a silently wrong answer).
    """
    t, gauges, stations = check_simulation_inputs(
        beam, drive, t_eval_s, gauge_positions_m, n_stations, max_stations=10_000
    )
    ne = check_int("n_elements", n_elements, 1, 200)
    form = check_choice("formulation", formulation, FORMULATIONS)
    a0 = check_non_negative("a0_per_s", a0_per_s)
    a1 = check_non_negative("a1_s", a1_s)
    rt = check_positive("rtol", rtol)
    at = check_positive("atol", atol)
    law = check_choice("damping_law", damping_law, DAMPING_LAWS)
    if law != "paper" and form != "corot":
        raise SimInputError("damping_law", f"{law!r} needs formulation 'corot', got {form!r}")
    if check_choice("curvature", curvature, CURVATURES) != "element" and form != "corot":
        raise SimInputError("curvature", f"{curvature!r} needs formulation 'corot', got {form!r}")
    if fixed_step_s is not None:
        fixed_step_s = check_positive("fixed_step_s", fixed_step_s)
        if method != "radau5":
            raise SimInputError("fixed_step_s", f"needs method 'radau5', got {method!r}")
    elif first_step_s is not None:
        raise SimInputError("first_step_s", "needs fixed_step_s")
    if stages != 3 and (fixed_step_s is None or form != "corot"):
        raise SimInputError(
            "stages", f"above 3 need fixed_step_s and formulation 'corot', got {stages!r}"
        )
    # the fused evaluation (closed-form Jacobians) at a fixed step only: see AncfSystem
    system = _make_system(form, beam, ne, drive, a0, a1, law, fixed_step_s is not None)
    if initial_state is None:
        y0 = system.initial_state()
    else:
        y0 = np.asarray(initial_state, dtype=float).ravel()
        if y0.shape != (system.n_state,) or not np.all(np.isfinite(y0)):
            raise SimInputError(
                "initial_state",
                f"must be {system.n_state} finite numbers for formulation {form!r} with "
                f"{ne} elements, got shape {np.shape(initial_state)}",
            )
    jac_stages = getattr(system, "jac_stages", None)
    if method == "auto":
        method = "BDF" if a1 > 0.0 else "Radau"
    traj = integrate(
        system.rhs,
        system.jac,
        t,
        y0,
        rtol=rt,
        atol=at,
        method=method,
        rhs_stages=getattr(system, "rhs_stages", None),
        jac_stages=jac_stages,
        rhs_jac_stages=getattr(system, "rhs_jac_stages", None),
        second_order=SECOND_ORDER,
        fixed_step_s=fixed_step_s,
        stages=stages,
        first_step_s=first_step_s,
    )
    lat, lon, strain = _deflections(system, traj.y, beam, stations, gauges)
    extra: dict[str, Any] = {} if fixed_step_s is None else {"fixed_step_s": fixed_step_s}
    if stages != 3:
        extra["stages"] = stages
    if curvature == "recovered" and gauges.size:
        assert isinstance(system, AncfSystem)
        kappa, change = recovered_curvature(system, traj.y, gauges)
        _, eps = system.sample(traj.y, gauges)
        strain = eps[..., 0] - beam.surface_offset_m * kappa
        scale = np.maximum(np.max(np.abs(strain), axis=0), 1e-300)
        per_gauge = beam.surface_offset_m * np.max(change, axis=0) / scale
        extra["curvature_fit_change"] = [float(x) for x in per_gauge]
    settings: dict[str, Any] = {
        "curvature": curvature,
        **extra,
        "formulation": form,
        "n_elements": ne,
        "rtol": rt,
        "atol": at,
        "damping": {"a0_per_s": a0, "a1_s": a1, "law": law},
        "method": method,
        "n_rhs": traj.n_rhs,
        "n_jac": traj.n_jac,
        "n_steps": traj.n_steps,
        "final_state": traj.y[-1].tolist(),
    }
    return SimResult(
        time_s=t,
        hub_angle_rad=np.asarray(drive.angle(t), dtype=float),
        tip_lateral_m=lat[:, -1].copy(),
        tip_longitudinal_m=lon[:, -1].copy(),
        stations_m=stations,
        station_lateral_m=lat,
        station_longitudinal_m=lon,
        gauge_positions_m=gauges,
        strain=strain,
        model=f"fe-{form}",
        wall_time_s=traj.wall_time_s,
        settings=settings,
    )


def _static_newton(
    residual_and_tangent: Any, x0: FloatArray, n_steps: int, merit: Any = None
) -> FloatArray:
    """Newton with load stepping: solve ``residual(x, lam) = 0`` for lam = 1/n .. 1.

    ``merit(x, lam)`` (the potential energy, when there is one) guards each step by
    backtracking, which keeps coarse, membrane-stiff meshes from overshooting."""
    x = x0.copy()
    for k in range(1, n_steps + 1):
        lam = k / n_steps
        dx_prev = math.inf
        for _ in range(100):
            res, kt = residual_and_tangent(x, lam)
            dx = np.linalg.solve(kt, -res)
            size = max(1e-12, float(np.max(np.abs(x))))
            dx_max = float(np.max(np.abs(dx)))
            step = 1.0
            if merit is not None and dx_max > 1e-3 * size:
                m0 = merit(x, lam)
                while step > 1e-6 and merit(x + step * dx, lam) > m0 + 1e-12 * abs(m0):
                    step *= 0.5
            x = x + step * dx
            if not np.all(np.isfinite(x)):
                raise StaticSolveError("non-finite state", k, n_steps)
            if step == 1.0 and (
                dx_max <= 1e-10 * size or (dx_max <= 1e-7 * size and dx_max >= 0.5 * dx_prev)
            ):
                break  # converged, or stagnating at round-off
            dx_prev = dx_max if step == 1.0 else math.inf
        else:
            raise StaticSolveError("Newton did not converge", k, n_steps)
    return x


def solve_static_fe(
    beam: BeamProperties,
    tip_force_n: float,
    *,
    n_elements: int = 8,
    formulation: str = "corot",
    gauge_positions_m: Sequence[float] | ArrayLike = (),
    n_stations: int = 21,
) -> SimResult:
    """Geometrically nonlinear static cantilever under a tip point load of fixed direction.

    The load of magnitude ``tip_force_n`` (N, >= 0) acts toward -lateral (the paper's
    hanging weight, the beam bending in the vertical plane, self-weight excluded as in
    §5.1). Newton's method with load stepping on the exact tangent.

    Returns
    -------
    SimResult
        One time sample (t = 0): equilibrium ``tip_lateral_m`` (negative),
        ``tip_longitudinal_m`` (negative: the tip is pulled in), station deflections and
        gauge strains; ``wall_time_s`` is the solve alone.
    """
    beam = check_beam(beam)
    p = check_non_negative("tip_force_n", tip_force_n)
    ne = check_int("n_elements", n_elements, 1, 400)
    form = check_choice("formulation", formulation, FORMULATIONS)
    gauges = check_gauges(gauge_positions_m, beam.length_m)
    ns = check_int("n_stations", n_stations, 2, 10_000)
    # rough size of the rotation decides the number of load steps
    theta = p * beam.length_m**2 / (2.0 * beam.bending_stiffness_n_m2)
    n_steps = max(1, math.ceil(theta / 0.05))
    t0 = time.perf_counter()
    system: Any
    if form == "corot":
        fe = AncfBeam(beam, ne)
        fr = fe.free
        load = np.zeros(fe.n_dof)
        load[4 * ne + 1] = -p
        load_f = load[fr]

        def ft(d: FloatArray, lam: float) -> tuple[FloatArray, FloatArray]:
            e = fe.e_ref.copy()
            e[fr] += d
            f, k = fe.tangent(e)
            return f[fr] - lam * load_f, k[np.ix_(fr, fr)]

        def energy(d: FloatArray, lam: float) -> float:
            e = fe.e_ref.copy()
            e[fr] += d
            return fe.strain_energy(e) - lam * float(load_f @ d)

        x = _static_newton(ft, np.zeros(fr.size), n_steps, energy)
        system = AncfSystem(beam, ne, _NoDrive(), 0.0, 0.0)
    else:
        fb = FlxdynBeam(beam, ne)
        x = _static_newton(
            lambda q, lam: fb.static_residual_and_tangent(q, lam * p), np.zeros(fb.n_q), n_steps
        )
        system = FlxdynSystem(beam, ne, _NoDrive(), 0.0, 0.0)
    wall = time.perf_counter() - t0
    y = np.concatenate([x, np.zeros_like(x)])[None, :]
    stations = np.linspace(0.0, beam.length_m, ns)
    lat, lon, strain = _deflections(system, y, beam, stations, gauges)
    return SimResult(
        time_s=np.zeros(1),
        hub_angle_rad=np.zeros(1),
        tip_lateral_m=lat[:, -1].copy(),
        tip_longitudinal_m=lon[:, -1].copy(),
        stations_m=stations,
        station_lateral_m=lat,
        station_longitudinal_m=lon,
        gauge_positions_m=gauges,
        strain=strain,
        model=f"fe-{form}",
        wall_time_s=wall,
        settings={
            "formulation": form,
            "n_elements": ne,
            "tip_force_n": p,
            "load_steps": n_steps,
            "static": True,
        },
    )


class _NoDrive:
    """A hub at rest (statics)."""

    def angle(self, t_s: ArrayLike) -> FloatArray:
        return np.zeros(np.shape(t_s))

    def rate(self, t_s: ArrayLike) -> FloatArray:
        return np.zeros(np.shape(t_s))

    def accel(self, t_s: ArrayLike) -> FloatArray:
        return np.zeros(np.shape(t_s))
