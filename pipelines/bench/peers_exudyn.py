"""Exudyn's 2-D ANCF cable on beambench's scenes: the side-by-side peer of ``bench sim``.

Exudyn (``pip install 'beambench[peers]'``) is imported lazily, inside the functions, so
this module imports without it; :func:`available` says whether it is there.

The model (:func:`simulate_exudyn`): ``n_elements`` ``ObjectANCFCable2D`` elements (cubic
Hermite position and slope nodes, ``NodePoint2DSlope1``) in the inertial frame. The hub is
not a body: the clamp node's four coordinates (position and slope, the same clamp as
beambench's ``corot`` FE) follow the prescribed rotation through four coordinate
constraints whose offsets are the clamp's displacement, ``c (cos phi - 1), c sin phi,
cos phi - 1, sin phi`` (c the hub offset). The run starts with the straight beam moving
rigidly with the hub, like beambench's. Exudyn's implicit generalized-alpha integrator
(index-3 constraints) runs at a fixed step; it has no error-controlled step size for
implicit methods, so a row's setting is (elements, step). The tip is read at every step and
turned into the hub frame: ``lateral = -sin(phi) x + cos(phi) y``, as
``SimResult.tip_lateral_m`` (relative to the rigid beam, positive toward increasing hub
angle).

Damping: beambench's Eq. 28 is ``(a0 M + a1 K_T) v`` with ``v`` the nodal rates relative to
the hub frame and ``K_T`` the full tangent stiffness. Exudyn's cable has strain-rate
(Kelvin-Voigt) damping, ``N = EA (eps + d_eps/EA eps')``, ``M = EI (K + d_K/EI K')``; with
``axialDamping = a1 EA`` and ``bendingDamping = a1 EI`` it reproduces ``a1 K_mat v``, the
material part of ``a1 K_T v``, exactly (strain rates are the same in the hub frame and the
inertial one). It cannot represent

- the geometric part ``a1 (N d2eps + M d2kappa) v``: a damping force from the current
  axial force and bending moment times the rotation rate of the centre line relative to
  the hub, which is not a strain rate; on the paper's scene it carries the (lagged)
  centrifugal tension and moves the tip by ~1.3e-2 of its amplitude;
- ``a0 M v``: mass-proportional damping of the rates relative to the hub has no native
  counterpart (a constant damping matrix on Exudyn's absolute coordinates would also damp
  the hub's rigid rotation); it is left out (~1e-3 of the tip here).

:func:`simulate_fe_kelvin_voigt` is beambench's own FE with Exudyn's damping law
(``simulate_fe(..., damping_law="material")``: the material ``a1`` term, optional
``a0 M v``), so the two codes can be compared on one model and the Eq. 28 gap measured by
itself.
"""

from __future__ import annotations

import importlib.util
import math
import time
from dataclasses import replace
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sim.beam import BeamProperties
from sim.drives import Drive, SinusoidDrive, SpinUpDrive
from sim.models.fe import simulate_fe
from sim.result import SimResult

FloatArray = NDArray[np.float64]

NEWTON_RTOL = 1e-10  # Exudyn's 1e-8 default leaves ~1e-5 m Newton noise on the paper's tip
NEWTON_ATOL_PER_EA = 1e-12  # absolute residual tolerance per unit EA (round-off floor)
MIXED_INTEGRATION = 2  # the cable's useReducedOrderIntegration without membrane locking


def available() -> bool:
    """Whether Exudyn can be imported (the optional ``peers`` extra)."""
    return importlib.util.find_spec("exudyn") is not None


def _angle_function(drive: Drive) -> Any:
    """The hub angle as a scalar function of time, cheap enough to be called per Newton
    iteration (numpy on scalars costs ~20 us per call: most of a step)."""
    if isinstance(drive, SinusoidDrive):
        amp, om, ph = drive.amplitude_rad, drive.omega_rad_s, drive.phase_rad
        return lambda t: amp * math.sin(om * t + ph)
    if isinstance(drive, SpinUpDrive):
        w, ts = drive.omega_s_rad_s, drive.ramp_s
        k = ts / (2.0 * math.pi)

        def spin(t: float) -> float:
            if t < 0.0:
                return 0.0
            if t < ts:
                return (w / ts) * (0.5 * t * t + k * k * (math.cos(t / k) - 1.0))
            return w * (t - 0.5 * ts)

        return spin
    return lambda t: float(drive.angle(t))


def _check_grid(t: FloatArray, step_s: float) -> tuple[NDArray[np.intp], float]:
    """Step indices of the output times on the fixed step grid, and the step: for evenly
    spaced outputs the largest step <= ``step_s`` that divides their interval."""
    if t.ndim != 1 or t.size < 2 or np.any(np.diff(t) <= 0.0) or not np.all(np.isfinite(t)):
        raise ValueError("t_eval_s must be a finite, strictly increasing 1-D array (>= 2 times)")
    if not math.isfinite(step_s) or step_s <= 0.0:
        raise ValueError(f"step_s must be a positive finite number, got {step_s!r}")
    dt = np.diff(t)
    if np.allclose(dt, dt[0], rtol=1e-9, atol=0.0):
        step_s = float(dt[0]) / math.ceil(float(dt[0]) / step_s - 1e-9)
    k = (t - t[0]) / step_s
    idx = np.rint(k).astype(np.intp)
    if np.max(np.abs(k - idx)) > 1e-6:
        raise ValueError(
            f"t_eval_s must lie on the step grid t_eval_s[0] + k * step_s (step_s = {step_s:g} s)"
        )
    return idx, step_s


def _new_system() -> tuple[Any, Any]:
    import exudyn as exu

    sc = exu.SystemContainer()
    return sc, sc.AddSystem()


def _add_cable(
    mbs: Any,
    beam: BeamProperties,
    n_elements: int,
    phi0: float,
    om0: float,
    a1: float,
    integration: int = 0,
) -> list[Any]:
    """Nodes and elements of the straight beam at hub angle ``phi0`` moving rigidly with
    the hub rate ``om0``; returns the node indices, clamp first."""
    import exudyn.itemInterface as ei

    c, le = beam.hub_offset_m, beam.length_m / n_elements
    ca, sa = math.cos(phi0), math.sin(phi0)
    nodes = []
    for k in range(n_elements + 1):
        s = c + k * le
        nodes.append(
            mbs.AddNode(
                ei.NodePoint2DSlope1(
                    referenceCoordinates=[s, 0.0, 1.0, 0.0],
                    initialCoordinates=[s * ca - s, s * sa, ca - 1.0, sa],
                    initialVelocities=[-om0 * s * sa, om0 * s * ca, -om0 * sa, om0 * ca],
                )
            )
        )
    for k in range(n_elements):
        mbs.AddObject(
            ei.ObjectANCFCable2D(
                length=le,
                massPerLength=beam.mass_per_length_kg_m,
                bendingStiffness=beam.bending_stiffness_n_m2,
                axialStiffness=beam.axial_stiffness_n,
                bendingDamping=a1 * beam.bending_stiffness_n_m2,
                axialDamping=a1 * beam.axial_stiffness_n,
                nodeNumbers=[nodes[k], nodes[k + 1]],
                useReducedOrderIntegration=integration,
            )
        )
    return nodes


def _clamp(mbs: Any, node: Any, beam: BeamProperties, angle: Any) -> None:
    """Constrain the clamp node's four coordinates to the hub; ``angle(t)`` or None
    (a hub at rest at angle 0)."""
    import exudyn.itemInterface as ei

    ground = mbs.AddNode(ei.NodePointGround(referenceCoordinates=[0.0, 0.0, 0.0]))
    m_ground = mbs.AddMarker(ei.MarkerNodeCoordinate(nodeNumber=ground, coordinate=0))
    c = beam.hub_offset_m
    offsets = [
        lambda p: c * math.cos(p) - c,
        lambda p: c * math.sin(p),
        lambda p: math.cos(p) - 1.0,
        math.sin,
    ]
    for i in range(4):
        m_node = mbs.AddMarker(ei.MarkerNodeCoordinate(nodeNumber=node, coordinate=i))
        if angle is None:
            mbs.AddObject(ei.CoordinateConstraint(markerNumbers=[m_ground, m_node]))
            continue

        mbs.AddObject(
            ei.CoordinateConstraint(
                markerNumbers=[m_ground, m_node],
                offsetUserFunction=_offset_function(offsets[i], angle),
            )
        )


def _offset_function(of_angle: Any, angle: Any) -> Any:
    """Exudyn's offset user function ``(mbs, t, itemNumber, offset) -> value``."""

    def offset(mbs: Any, t: float, item: Any, off: float) -> float:
        return float(of_angle(angle(t)))

    return offset


def _check_beam(beam: object, n_elements: int) -> BeamProperties:
    if not isinstance(beam, BeamProperties):
        raise TypeError(f"beam must be a sim.beam.BeamProperties, got {type(beam).__name__}")
    if isinstance(n_elements, bool) or not isinstance(n_elements, int) or not 1 <= n_elements:
        raise ValueError(f"n_elements must be an int >= 1, got {n_elements!r}")
    return beam


def simulate_exudyn(
    beam: BeamProperties,
    drive: Drive,
    t_eval_s: ArrayLike,
    *,
    n_elements: int,
    step_s: float,
    a1_s: float = 0.0,
    spectral_radius: float = 0.9,
    newton_rtol: float = NEWTON_RTOL,
    integration: int = MIXED_INTEGRATION,
) -> SimResult:
    """Simulate the beam on the prescribed hub with Exudyn's ANCF cable.

    Parameters
    ----------
    beam, drive : as for :func:`sim.models.fe.simulate_fe`.
    t_eval_s : (N,) output times on the step grid ``t_eval_s[0] + k step_s``.
    n_elements : number of ``ObjectANCFCable2D`` elements.
    step_s : the fixed time step of the generalized-alpha integrator, s; for evenly spaced
        outputs it is shortened to divide their interval (``settings["step_s"]``).
    a1_s : stiffness-proportional damping, mapped to ``axialDamping = a1 EA`` and
        ``bendingDamping = a1 EI`` (strain-rate damping; see the module docstring for what
        of Eq. 28 this is and is not). There is no ``a0``.
    spectral_radius : generalized-alpha's rho_infinity (Exudyn's default 0.9).
    newton_rtol : Newton's relative residual tolerance.
    integration : the cable's ``useReducedOrderIntegration``: 0 (Gauss order 9 axial,
        5 bending), 1 (7 / 3) or 2 (mixed Lobatto / Gauss, the default here: the others
        lock: on the paper's scene 4 elements are 2.3e-3 off with 0 or 1, 1.8e-4 with 2).

    Returns
    -------
    SimResult
        ``tip_lateral_m`` and ``tip_longitudinal_m`` in the hub frame; stations are the
        clamp and the tip only, no gauges; ``wall_time_s`` is ``SolveDynamic`` alone.
    """
    import exudyn as exu
    import exudyn.itemInterface as ei

    beam = _check_beam(beam, n_elements)
    t = np.asarray(t_eval_s, dtype=float)
    idx, step_s = _check_grid(t, step_s)
    if not math.isfinite(a1_s) or a1_s < 0.0:
        raise ValueError(f"a1_s must be a non-negative finite number, got {a1_s!r}")
    angle = _angle_function(drive)
    t0 = float(t[0])
    _, mbs = _new_system()
    if integration not in (0, 1, 2):
        raise ValueError(f"integration must be 0, 1 or 2, got {integration!r}")
    nodes = _add_cable(mbs, beam, n_elements, angle(t0), float(drive.rate(t0)), a1_s, integration)
    _clamp(mbs, nodes[0], beam, angle)
    sensor = mbs.AddSensor(
        ei.SensorNode(
            nodeNumber=nodes[-1],
            storeInternal=True,
            writeToFile=False,
            outputVariableType=exu.OutputVariableType.Position,
        )
    )
    mbs.Assemble()
    ss = exu.SimulationSettings()
    ti = ss.timeIntegration
    ti.startTime, ti.endTime = t0, t0 + int(idx[-1]) * step_s
    ti.numberOfSteps = int(idx[-1])
    ti.verboseMode = 0
    ti.adaptiveStep = False  # a fixed-step method: fail rather than change the step
    ti.newton.relativeTolerance = newton_rtol
    ti.newton.absoluteTolerance = NEWTON_ATOL_PER_EA * beam.axial_stiffness_n
    ti.generalizedAlpha.spectralRadius = spectral_radius
    ss.solution.file.write = False
    ss.solution.sensors.writePeriod = step_s
    tic = time.perf_counter()
    exu.SolveDynamic(mbs, ss, solverType=exu.DynamicSolverType.GeneralizedAlpha)
    wall = time.perf_counter() - tic
    data = np.asarray(mbs.GetSensorStoredData(sensor), dtype=float)
    rows = np.rint((data[:, 0] - t0) / step_s).astype(np.intp)
    pos = np.full((int(idx[-1]) + 1, 2), np.nan)
    pos[rows] = data[:, 1:3]
    xy = pos[idx]
    if not np.all(np.isfinite(xy)):
        raise RuntimeError("Exudyn did not record the tip at every output time")
    phi = np.array([angle(tk) for tk in t])
    cp, sp = np.cos(phi), np.sin(phi)
    lat = -sp * xy[:, 0] + cp * xy[:, 1]
    lon = cp * xy[:, 0] + sp * xy[:, 1] - (beam.hub_offset_m + beam.length_m)
    stations = np.array([0.0, beam.length_m])
    return SimResult(
        time_s=t,
        hub_angle_rad=np.asarray(drive.angle(t), dtype=float),
        tip_lateral_m=lat,
        tip_longitudinal_m=lon,
        stations_m=stations,
        station_lateral_m=np.stack([np.zeros_like(lat), lat], axis=1),
        station_longitudinal_m=np.stack([np.zeros_like(lon), lon], axis=1),
        gauge_positions_m=np.zeros(0),
        strain=np.zeros((t.size, 0)),
        model="exudyn-ancf",
        wall_time_s=wall,
        settings={
            "n_elements": n_elements,
            "step_s": step_s,
            "solver": "GeneralizedAlpha",
            "spectral_radius": spectral_radius,
            "newton_rtol": newton_rtol,
            "integration": integration,
            "axial_damping_n_s": a1_s * beam.axial_stiffness_n,
            "bending_damping_n_m2_s": a1_s * beam.bending_stiffness_n_m2,
            "exudyn_version": exu.__version__,
        },
    )


def static_tip_deflection_m(
    beam: BeamProperties,
    tip_force_n: float,
    n_elements: int,
    integration: int = MIXED_INTEGRATION,
) -> float:
    """Static lateral tip deflection (m, negative) of Exudyn's clamped cable under a tip
    force ``tip_force_n`` (N) of fixed direction toward -lateral (geometrically nonlinear)."""
    import exudyn as exu
    import exudyn.itemInterface as ei

    beam = _check_beam(beam, n_elements)
    _, mbs = _new_system()
    nodes = _add_cable(mbs, beam, n_elements, 0.0, 0.0, 0.0, integration)
    _clamp(mbs, nodes[0], beam, None)
    marker = mbs.AddMarker(ei.MarkerNodePosition(nodeNumber=nodes[-1]))
    mbs.AddLoad(ei.LoadForceVector(markerNumber=marker, loadVector=[0.0, -tip_force_n, 0.0]))
    mbs.Assemble()
    ss = exu.SimulationSettings()
    ss.staticSolver.verboseMode = 0
    ss.staticSolver.newton.relativeTolerance = 1e-12
    ss.staticSolver.newton.absoluteTolerance = 1e-14 * beam.axial_stiffness_n
    ss.solution.file.write = False
    exu.SolveStatic(mbs, ss)
    return float(mbs.GetNodeOutput(nodes[-1], exu.OutputVariableType.Displacement)[1])


def first_frequency_hz(
    beam: BeamProperties, n_elements: int, integration: int = MIXED_INTEGRATION
) -> float:
    """First bending frequency (Hz) of Exudyn's clamped-free cable, from its eigenvalues
    with the clamp node's four coordinates fixed."""
    import exudyn as exu

    beam = _check_beam(beam, n_elements)
    _, mbs = _new_system()
    _add_cable(mbs, beam, n_elements, 0.0, 0.0, 0.0, integration)
    mbs.Assemble()
    freqs, _ = exu.solver.ComputeODE2Eigenvalues(
        mbs, constrainedCoordinates=[0, 1, 2, 3], convert2Frequencies=True
    )
    return float(np.min(freqs))


def simulate_fe_kelvin_voigt(
    beam: BeamProperties,
    drive: Drive,
    t_eval_s: ArrayLike,
    *,
    n_elements: int,
    a0_per_s: float = 0.0,
    a1_s: float = 0.0,
    rtol: float = 1e-6,
    atol: float = 1e-9,
    method: str = "BDF",
) -> SimResult:
    """beambench's ``corot`` FE with Exudyn's damping law (``damping_law="material"`` of
    :func:`sim.models.fe.simulate_fe`); returns the tip only (stations clamp and tip),
    ``wall_time_s`` the integration."""
    beam = _check_beam(beam, n_elements)
    res = simulate_fe(
        beam,
        drive,
        t_eval_s,
        n_elements=n_elements,
        a0_per_s=a0_per_s,
        a1_s=a1_s,
        n_stations=2,
        rtol=rtol,
        atol=atol,
        method=method,
        damping_law="material",
    )
    return replace(
        res,
        model="fe-corot-kelvin-voigt",
        settings={"n_elements": n_elements, "rtol": rtol, "atol": atol, "method": method},
    )
