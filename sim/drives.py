"""Prescribed hub motions: angle, rate and acceleration as functions of time.

Every drive is vectorised over ``t_s`` and returns radians, rad/s and rad/s^2. The hub
angle is measured in the frame the drive names (for the paper's sinusoid: about
mid-stroke); beam models only use it through its derivatives and the rotation of the
hub frame, so a constant offset does not change the deflection.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import ArrayLike, NDArray

FloatArray = NDArray[np.float64]


@runtime_checkable
class Drive(Protocol):
    """A prescribed hub angle Phi(t) with consistent first and second derivatives."""

    def angle(self, t_s: ArrayLike) -> FloatArray: ...

    def rate(self, t_s: ArrayLike) -> FloatArray: ...

    def accel(self, t_s: ArrayLike) -> FloatArray: ...


@dataclass(frozen=True)
class SinusoidDrive:
    """Phi = amplitude * sin(omega * t + phase) (paper Eq. 53: 0.7669 sin(4.970 t))."""

    amplitude_rad: float = 0.7669
    omega_rad_s: float = 4.970
    phase_rad: float = 0.0

    def angle(self, t_s: ArrayLike) -> FloatArray:
        t = np.asarray(t_s, dtype=float)
        return self.amplitude_rad * np.sin(self.omega_rad_s * t + self.phase_rad)

    def rate(self, t_s: ArrayLike) -> FloatArray:
        t = np.asarray(t_s, dtype=float)
        return self.amplitude_rad * self.omega_rad_s * np.cos(self.omega_rad_s * t + self.phase_rad)

    def accel(self, t_s: ArrayLike) -> FloatArray:
        t = np.asarray(t_s, dtype=float)
        w = self.omega_rad_s
        return -self.amplitude_rad * w * w * np.sin(w * t + self.phase_rad)
