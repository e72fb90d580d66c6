"""Input checks shared by the beam models, the statics and the scenes (moved here from
``sim/models/rigid.py``).

Each check validates one argument at the public boundary and returns it in the form the
caller computes with; a bad value raises :class:`sim.errors.SimInputError` (a ``ValueError``)
whose message starts with the parameter's name, a wrong type a ``TypeError``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sim.beam import BeamProperties
from sim.drives import Drive
from sim.errors import SimInputError

FloatArray = NDArray[np.float64]


def check_positive(name: str, value: float) -> float:
    """``value`` as a float, refused unless finite and > 0."""
    v = float(value)
    if not math.isfinite(v) or v <= 0.0:
        raise SimInputError(name, f"must be a positive finite number, got {value!r}")
    return v


def check_non_negative(name: str, value: float) -> float:
    """``value`` as a float, refused unless finite and >= 0."""
    v = float(value)
    if not math.isfinite(v) or v < 0.0:
        raise SimInputError(name, f"must be a non-negative finite number, got {value!r}")
    return v


def check_int(name: str, value: object, lo: int, hi: int | None = None) -> int:
    """``value`` as an int in ``[lo, hi]`` (no upper bound for ``hi=None``); ``bool`` is not
    an integer here."""
    if isinstance(value, bool) or not isinstance(value, int | np.integer):
        raise TypeError(f"{name} must be an integer, got {type(value).__name__}")
    v = int(value)
    if hi is None and v < lo:
        raise SimInputError(name, f"must be at least {lo}, got {value!r}")
    if hi is not None and not lo <= v <= hi:
        raise SimInputError(name, f"must be in [{lo}, {hi}], got {value!r}")
    return v


def check_choice(name: str, value: str, choices: Sequence[str]) -> str:
    """``value`` if it is one of ``choices``."""
    if value not in choices:
        raise SimInputError(name, f"must be one of {', '.join(choices)}, got {value!r}")
    return value


def check_beam(beam: object) -> BeamProperties:
    if not isinstance(beam, BeamProperties):
        raise TypeError(f"beam must be a sim.beam.BeamProperties, got {type(beam).__name__}")
    return beam


def check_drive(drive: object) -> Drive:
    if not isinstance(drive, Drive):
        raise TypeError(
            f"drive must implement the sim.drives.Drive protocol (angle, rate, accel), "
            f"got {type(drive).__name__}"
        )
    return drive


def check_times(t_eval_s: ArrayLike) -> FloatArray:
    """(N,) output times: a non-empty, finite, strictly increasing 1-D array, s."""
    t = np.asarray(t_eval_s, dtype=float)
    if t.ndim != 1 or t.size < 1:
        raise SimInputError("t_eval_s", f"must be a non-empty 1-D array, got shape {t.shape}")
    if not np.all(np.isfinite(t)):
        raise SimInputError("t_eval_s", "must be finite")
    if t.size > 1 and np.any(np.diff(t) <= 0.0):
        raise SimInputError("t_eval_s", "must be strictly increasing")
    return t


def check_gauges(gauge_positions_m: Sequence[float] | ArrayLike, length_m: float) -> FloatArray:
    """(G,) gauge distances from the clamp, each on the beam (within [0, ``length_m``]), m."""
    gauges = np.atleast_1d(np.asarray(gauge_positions_m, dtype=float)).reshape(-1)
    if np.any(~np.isfinite(gauges)) or np.any(gauges < 0.0) or np.any(gauges > length_m):
        raise SimInputError(
            "gauge_positions_m",
            f"must lie on the beam, within [0, {length_m!r}] m, got {gauges.tolist()}",
        )
    return gauges


def check_simulation_inputs(
    beam: object,
    drive: object,
    t_eval_s: ArrayLike,
    gauge_positions_m: Sequence[float] | ArrayLike,
    n_stations: int,
    *,
    max_stations: int | None = None,
) -> tuple[FloatArray, FloatArray, FloatArray]:
    """Validate the arguments every beam model takes.

    Returns
    -------
    t : (N,) output times (s); gauges : (G,) gauge positions (m); stations : (S,) station
    positions from the clamp, 0 and L included (m).
    """
    checked = check_beam(beam)
    check_drive(drive)
    t = check_times(t_eval_s)
    gauges = check_gauges(gauge_positions_m, checked.length_m)
    ns = check_int("n_stations", n_stations, 2, max_stations)
    return t, gauges, np.linspace(0.0, checked.length_m, ns)
