"""Uniform planar beam properties, as the models use them.

``BeamProperties`` is independent of the rig file so that scenes with other beams
(the spin-up benchmark beam) use the same models.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sim.config import BeamConfig
from sim.errors import SimInputError


@dataclass(frozen=True)
class BeamProperties:
    """A uniform Euler-Bernoulli beam clamped to a rigid hub at ``hub_offset_m`` from the
    hub's pivot.

    Parameters
    ----------
    length_m : free length, clamp to tip.
    hub_offset_m : pivot to clamp along the hub axis (0 for a beam clamped on the axis).
    mass_per_length_kg_m : rho * A.
    bending_stiffness_n_m2 : E * I.
    axial_stiffness_n : E * A.
    surface_offset_m : neutral axis to the gauged surface (z of Eq. 50; t / 2).
    """

    length_m: float
    hub_offset_m: float
    mass_per_length_kg_m: float
    bending_stiffness_n_m2: float
    axial_stiffness_n: float
    surface_offset_m: float = 0.0

    def __post_init__(self) -> None:
        for name in (
            "length_m",
            "mass_per_length_kg_m",
            "bending_stiffness_n_m2",
            "axial_stiffness_n",
        ):
            v = getattr(self, name)
            if not math.isfinite(v) or v <= 0.0:
                raise SimInputError(name, f"must be a positive finite number, got {v!r}")
        for name in ("hub_offset_m", "surface_offset_m"):
            v = getattr(self, name)
            if not math.isfinite(v) or v < 0.0:
                raise SimInputError(name, f"must be a non-negative finite number, got {v!r}")

    @classmethod
    def from_config(cls, beam: BeamConfig) -> BeamProperties:
        return cls(
            length_m=beam.length_m,
            hub_offset_m=beam.hub_offset_m,
            mass_per_length_kg_m=beam.mass_per_length_kg_m,
            bending_stiffness_n_m2=beam.bending_stiffness_n_m2,
            axial_stiffness_n=beam.axial_stiffness_n,
            surface_offset_m=beam.surface_offset_m,
        )

    @property
    def mass_kg(self) -> float:
        return self.mass_per_length_kg_m * self.length_m


def spin_up_beam() -> BeamProperties:
    """The Kane / Simo-Vu-Quoc spin-up beam: L = 10 m, rhoA = 1.2 kg/m, EI = 14000 N m^2,
    EA = 2.8e7 N, clamped on the rotation axis."""
    return BeamProperties(
        length_m=10.0,
        hub_offset_m=0.0,
        mass_per_length_kg_m=1.2,
        bending_stiffness_n_m2=14000.0,
        axial_stiffness_n=2.8e7,
        surface_offset_m=0.0,
    )
