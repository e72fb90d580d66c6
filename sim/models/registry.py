"""The beam models by name, in one registry: what ``beambench sim --model``, the scenes, the
rig's ``synthetic.model`` and the simulation of a processed run accept.

Every model is run through :func:`simulate` with one signature (beam, drive, output times,
damping, gauges, tolerance, ...), and :data:`MODELS` is the list of names that the command
line's choices and the rig's validation use. A model ignores the settings that do not apply
to it (``n_modes`` means nothing to the finite elements); ``tol=None`` leaves each model at
its own default tolerance, so a caller that wants another one says so at its call site.

- ``auto``: the cheapest model whose estimated error is below ``tol``
  (:func:`sim.models.model_choice.simulate_auto`, default tol 1e-4);
- ``rigid``: no deflection (:func:`sim.models.rigid.simulate_rigid`);
- ``modal``: ``n_modes`` assumed modes (:func:`sim.models.modal.simulate_modal`, default
  rtol 1e-8), or with ``nonlinear=True`` the third-order model
  (:func:`sim.models.modal_nonlinear.simulate_modal_nonlinear`);
- ``fe``: the exact finite elements (:func:`sim.models.fe.simulate_fe`, default rtol 1e-6).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType
from typing import Any

from numpy.typing import ArrayLike

from sim.beam import BeamProperties
from sim.checks import check_choice
from sim.config import DAMPING_LAWS
from sim.drives import Drive
from sim.errors import SimInputError
from sim.models.fe import simulate_fe
from sim.models.modal import simulate_modal
from sim.models.modal_nonlinear import simulate_modal_nonlinear
from sim.models.model_choice import simulate_auto
from sim.models.rigid import simulate_rigid
from sim.result import SimResult


@dataclass(frozen=True)
class ModelSettings:
    """Everything a model takes besides the beam, the drive and the output times.

    ``tol`` is each model's accuracy setting (``auto``: its ``tol``; ``modal`` and ``fe``:
    the integrator's rtol; ``rigid``: none), ``None`` for the model's own default.
    ``n_modes``, ``nonlinear`` and ``stiffening`` apply to ``modal`` only. ``damping_law``
    (:data:`sim.config.DAMPING_LAWS`) is the ``a1`` term: ``"paper"`` (Eq. 28, tangent
    stiffness) or ``"material"`` (Kelvin-Voigt, strain rates).
    """

    a0_per_s: float = 0.0
    a1_s: float = 0.0
    damping_law: str = "paper"
    gauge_positions_m: Sequence[float] | ArrayLike = ()
    n_stations: int = 21
    tol: float | None = None
    n_modes: int = 4
    nonlinear: bool = False
    stiffening: bool = True


#: a model: (beam, drive, output times, settings) -> result
Model = Callable[[BeamProperties, Drive, ArrayLike, ModelSettings], SimResult]


def _rigid(beam: BeamProperties, drive: Drive, t_s: ArrayLike, s: ModelSettings) -> SimResult:
    return simulate_rigid(
        beam, drive, t_s, gauge_positions_m=s.gauge_positions_m, n_stations=s.n_stations
    )


def _modal(beam: BeamProperties, drive: Drive, t_s: ArrayLike, s: ModelSettings) -> SimResult:
    kw: dict[str, Any] = {
        "n_modes": s.n_modes,
        "a0_per_s": s.a0_per_s,
        "a1_s": s.a1_s,
        "gauge_positions_m": s.gauge_positions_m,
        "n_stations": s.n_stations,
        "damping_law": s.damping_law,
    }
    if s.tol is not None:
        kw["rtol"] = s.tol
    if s.nonlinear:
        if not s.stiffening:
            raise SimInputError(
                "nonlinear", "needs stiffening: the third-order modal model always has it"
            )
        return simulate_modal_nonlinear(beam, drive, t_s, **kw)
    return simulate_modal(beam, drive, t_s, stiffening=s.stiffening, **kw)


def _fe(beam: BeamProperties, drive: Drive, t_s: ArrayLike, s: ModelSettings) -> SimResult:
    kw: dict[str, Any] = {} if s.tol is None else {"rtol": s.tol}
    return simulate_fe(
        beam,
        drive,
        t_s,
        a0_per_s=s.a0_per_s,
        a1_s=s.a1_s,
        gauge_positions_m=s.gauge_positions_m,
        n_stations=s.n_stations,
        damping_law=s.damping_law,
        **kw,
    )


def _auto(beam: BeamProperties, drive: Drive, t_s: ArrayLike, s: ModelSettings) -> SimResult:
    kw: dict[str, Any] = {} if s.tol is None else {"tol": s.tol}
    return simulate_auto(
        beam,
        drive,
        t_s,
        a0_per_s=s.a0_per_s,
        a1_s=s.a1_s,
        gauge_positions_m=s.gauge_positions_m,
        n_stations=s.n_stations,
        damping_law=s.damping_law,
        **kw,
    )


REGISTRY: Mapping[str, Model] = MappingProxyType(
    {"auto": _auto, "rigid": _rigid, "modal": _modal, "fe": _fe}
)
#: the model names, in the order the command line lists them
MODELS: tuple[str, ...] = tuple(REGISTRY)


def check_model(model: str) -> str:
    """``model`` if it names a registered model (:data:`MODELS`)."""
    return check_choice("model", model, MODELS)


def simulate(
    model: str,
    beam: BeamProperties,
    drive: Drive,
    t_eval_s: ArrayLike,
    *,
    a0_per_s: float = 0.0,
    a1_s: float = 0.0,
    gauge_positions_m: Sequence[float] | ArrayLike = (),
    n_stations: int = 21,
    tol: float | None = None,
    n_modes: int = 4,
    nonlinear: bool = False,
    stiffening: bool = True,
    damping_law: str = "paper",
) -> SimResult:
    """Simulate the beam on the prescribed hub with the model named ``model``.

    Parameters
    ----------
    model : one of :data:`MODELS`.
    beam, drive : the beam and its prescribed hub motion.
    t_eval_s : (N,) strictly increasing output times, s.
    a0_per_s, a1_s : proportional damping of Eq. 28.
    damping_law : ``"paper"`` or ``"material"`` (:class:`ModelSettings`).
    gauge_positions_m : (G,) gauge distances from the clamp, m.
    n_stations : equally spaced shape stations, clamp and tip included.
    tol : the model's tolerance (see :class:`ModelSettings`); ``None``: its own default.
    n_modes, nonlinear, stiffening : ``modal`` only: the number of modes, the third-order
        model, the centrifugal stiffening (``False``: seed 001's linear model).

    Raises
    ------
    sim.errors.SimInputError
        for an unknown model name or settings the model refuses.
    """
    run = REGISTRY[check_model(model)]
    settings = ModelSettings(
        a0_per_s=a0_per_s,
        a1_s=a1_s,
        damping_law=check_choice("damping_law", damping_law, DAMPING_LAWS),
        gauge_positions_m=gauge_positions_m,
        n_stations=n_stations,
        tol=tol,
        n_modes=n_modes,
        nonlinear=nonlinear,
        stiffening=stiffening,
    )
    return run(beam, drive, t_eval_s, settings)
