"""What a simulation returns: one record shared by every beam model and scene."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sim.errors import SimInputError

FloatArray = NDArray[np.float64]


@dataclass(frozen=True)
class SimResult:
    """Time histories of a beam on a prescribed hub.

    Deflections are relative to the hypothetical rigid beam (the hub line extended),
    expressed in the hub frame: ``lateral`` perpendicular to the rigid beam, positive
    toward increasing hub angle; ``longitudinal`` along it, negative when the point is
    pulled in. Strains are surface strains at the gauges (Eqs. 50-52) on the
    surface facing increasing hub angle (z = +t/2 on the +lateral side):
    strain = du/dx - (t/2) d2w/dx2 in the linear part, so a beam bent toward -lateral
    near the clamp (as under the static tip weight, which acts toward -lateral) reads
    positive strain, like the paper's Table 2.

    Attributes
    ----------
    time_s : (N,) output times.
    hub_angle_rad : (N,) prescribed hub angle.
    tip_lateral_m, tip_longitudinal_m : (N,) tip deflection.
    stations_m : (S,) distances from the clamp where the shape is sampled (0 and L included).
    station_lateral_m, station_longitudinal_m : (N, S) deflection at the stations.
    gauge_positions_m : (G,) distances from the clamp.
    strain : (N, G) surface strain at the gauges (dimensionless, m/m).
    model : model name ("rigid", "modal", "fe-flxdyn", "fe-corot", ...).
    settings : model settings and, for ``auto``, the choice and its error estimate.
    wall_time_s : the solve alone, not set-up or output.
    """

    time_s: FloatArray
    hub_angle_rad: FloatArray
    tip_lateral_m: FloatArray
    tip_longitudinal_m: FloatArray
    stations_m: FloatArray
    station_lateral_m: FloatArray
    station_longitudinal_m: FloatArray
    gauge_positions_m: FloatArray
    strain: FloatArray
    model: str
    wall_time_s: float
    settings: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        n = self.time_s.shape[0]
        for name in ("hub_angle_rad", "tip_lateral_m", "tip_longitudinal_m"):
            if getattr(self, name).shape != (n,):
                raise SimInputError(
                    name, f"must have shape ({n},), got {getattr(self, name).shape}"
                )
        s = self.stations_m.shape[0]
        for name in ("station_lateral_m", "station_longitudinal_m"):
            if getattr(self, name).shape != (n, s):
                raise SimInputError(
                    name, f"must have shape ({n}, {s}), got {getattr(self, name).shape}"
                )
        g = self.gauge_positions_m.shape[0]
        if self.strain.shape != (n, g):
            raise SimInputError("strain", f"must have shape ({n}, {g}), got {self.strain.shape}")

    # -- row operations (per output time) -------------------------------------------------
    _PER_TIME = (
        "time_s",
        "hub_angle_rad",
        "tip_lateral_m",
        "tip_longitudinal_m",
        "station_lateral_m",
        "station_longitudinal_m",
        "strain",
    )

    def rows(self, index: ArrayLike | slice) -> SimResult:
        """The result at a subset of its output times (``index`` into ``time_s``)."""
        from dataclasses import replace

        new: dict[str, Any] = {k: getattr(self, k)[index] for k in self._PER_TIME}
        return replace(self, **new)

    def held_before(self, t_before_s: ArrayLike) -> SimResult:
        """This result with its first state held still at the earlier times ``t_before_s``
        (a beam held deflected until it is released)."""
        from dataclasses import replace

        t = np.asarray(t_before_s, dtype=float).reshape(-1)
        if t.size and not t[-1] < self.time_s[0]:
            raise SimInputError("t_before_s", "must all be earlier than the result's first time")
        new: dict[str, Any] = {
            k: np.concatenate([np.repeat(getattr(self, k)[:1], t.size, axis=0), getattr(self, k)])
            for k in self._PER_TIME
            if k != "time_s"
        }
        return replace(self, time_s=np.concatenate([t, self.time_s]), **new)
