"""Planar four-bar kinematics in the frame of the paper's Eqs. 1-2.

Crank pivot O2 at the origin, rocker pivot O4 at (a1, 0); crank tip
P = a2 (cos psi, sin psi) (Eq. 1), rocker tip Q = (a1 + a4 cos phi, a4 sin phi) (Eq. 2),
loop closure |P - Q| = a3 (Eqs. 3-4).

The rocker angle is found as the intersection of the circle of radius a4 about O4 with the
circle of radius a3 about P, by ``atan2`` of the loop-closure components: with
d = P - O4 (length r, direction theta_d) the law of cosines gives the angle gamma between d
and the rocker, and phi = theta_d - branch * gamma. No division by B + C (the half-angle form
of Eqs. 7-8) happens anywhere, so no position is singular except the dead-centre positions of
the coupler and rocker themselves (where a crank-rocker cannot be).

What the paper prints, checked against Eq. 4 (see ``paper_eq8_rocker_angle_rad``):

- Eq. 7 solves the half-angle quadratic of Eq. 6 wrongly: the roots of
  (C - B) t^2 + 2 A t + (B + C) = 0 are t = (-A +/- sqrt(A^2 + B^2 - C^2)) / (C - B), while
  Eq. 7 prints (A +/- sqrt) / (B + C) = -1 / t. The printed Eq. 8 is therefore phi + pi of a
  true solution. Taking the printed "+" sign gives, after adding pi, the branch with the rocker
  tip above the ground line (y_Q > 0), the one whose values at psi = 0 and pi are the paper's
  62.598 deg and 150.474 deg. ``branch=+1`` is that assembly.
- Eq. 9 as printed, 2 atan((3/5)(4 sin psi + 2 sqrt(5056 - 2601 cos^2 psi + 765 cos psi))
  / (99 cos psi + 125)), matches neither: it gives 33.82 deg at psi = 0. Its denominator and
  radicand are right (they are C - B and A^2 + B^2 - C^2 scaled by 117/5 and 117^2/144),
  the numerator is garbled; the correct root is
  phi = 2 atan((3/5)(4 sqrt(5056 - 2601 cos^2 psi + 765 cos psi) - 39 sin psi)
  / (99 cos psi + 125)) (``corrected_eq9_rocker_angle_rad``), equal to ``branch=+1``.
- Eq. 10 sets d f / d phi to zero but the extrema of phi(psi) are where d phi / d psi = 0,
  i.e. where the crank and the coupler are collinear (dead centres): psi ~ 8.8 deg and
  186.4 deg for the paper's links, not psi = 0 and pi. The true extrema are
  61.93 deg and 150.83 deg (range 88.90 deg), against the paper's 62.598 / 150.474 deg
  (87.876 deg), which are only the rocker angles at psi = 0 and pi.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike, NDArray

from sim.config import LinkageConfig
from sim.errors import SimInputError

FloatArray = NDArray[np.float64]

#: The paper's printed extrema (Eqs. 10-11), at psi = 0 and psi = pi, for contrast only.
PAPER_ROCKER_MIN_RAD = math.radians(62.598)
PAPER_ROCKER_MAX_RAD = math.radians(150.474)
PAPER_CRANK_AT_MIN_RAD = 0.0
PAPER_CRANK_AT_MAX_RAD = math.pi


def classify_grashof(ground_m: float, crank_m: float, coupler_m: float, rocker_m: float) -> str:
    """Grashof class of a four-bar.

    Returns one of ``"crank-rocker"`` (shortest link is the crank), ``"double-crank"``
    (shortest is the ground), ``"double-rocker"`` (Grashof, shortest is the coupler),
    ``"change-point"`` (s + l = p + q: links can fold flat) or ``"non-grashof"``
    (triple rocker: no link turns fully).
    """
    lengths = {"ground_m": ground_m, "crank_m": crank_m, "coupler_m": coupler_m}
    lengths["rocker_m"] = rocker_m
    for name, value in lengths.items():
        if not math.isfinite(value) or value <= 0.0:
            raise SimInputError(name, f"must be a positive finite number, got {value!r}")
    ordered = sorted(lengths.values())
    s, p, q, l = ordered
    excess = (s + l) - (p + q)
    if abs(excess) <= 1e-12 * l:
        return "change-point"
    if excess > 0.0:
        return "non-grashof"
    shortest = min(lengths, key=lambda k: lengths[k])
    if shortest == "crank_m":
        return "crank-rocker"
    if shortest == "ground_m":
        return "double-crank"
    if shortest == "coupler_m":
        return "double-rocker"
    # Shortest is the rocker: the rocker turns fully and the crank rocks (rocker-crank).
    return "rocker-crank"


@dataclass(frozen=True)
class RockerExtrema:
    """Rocker extrema at the dead-centre positions, with the crank angles where they occur.

    Angles in radians in the frame of Eqs. 1-2; ``crank_at_*`` in [0, 2 pi).
    """

    rocker_min_rad: float
    crank_at_min_rad: float
    rocker_max_rad: float
    crank_at_max_rad: float

    @property
    def range_rad(self) -> float:
        return self.rocker_max_rad - self.rocker_min_rad

    @property
    def mid_rad(self) -> float:
        return 0.5 * (self.rocker_max_rad + self.rocker_min_rad)


class FourBar:
    """A planar four-bar with the crank as input (paper §2.1).

    Parameters
    ----------
    ground_m, crank_m, coupler_m, rocker_m : link lengths a1, a2, a3, a4 (m).
    branch : +1 for the assembly with the rocker tip above the ground line (the paper's
        "elbow up", whose angles at psi = 0, pi are 62.598 / 150.474 deg), -1 for its mirror.
    require_crank_rocker : refuse (``ValueError``) anything but a Grashof crank-rocker. With
        ``False`` any linkage is accepted and a crank angle at which it cannot assemble is
        refused when asked for.
    """

    def __init__(
        self,
        ground_m: float,
        crank_m: float,
        coupler_m: float,
        rocker_m: float,
        branch: int = 1,
        *,
        require_crank_rocker: bool = True,
    ) -> None:
        self.grashof = classify_grashof(ground_m, crank_m, coupler_m, rocker_m)
        if branch not in (1, -1):
            raise SimInputError("branch", f"must be +1 or -1, got {branch!r}")
        if require_crank_rocker and self.grashof != "crank-rocker":
            raise SimInputError(
                "crank_m",
                f"cannot drive the rocker: the linkage (ground {ground_m!r}, crank {crank_m!r}, "
                f"coupler {coupler_m!r}, rocker {rocker_m!r} m) is {self.grashof}, not a "
                "crank-rocker (Grashof with the crank as shortest link)",
            )
        self.ground_m = float(ground_m)
        self.crank_m = float(crank_m)
        self.coupler_m = float(coupler_m)
        self.rocker_m = float(rocker_m)
        self.branch = int(branch)
        self._ref_rad = 0.0
        self._ref_rad = float(self._raw_rocker_angle(np.array([self._first_assembled()]))[0])

    @classmethod
    def from_config(cls, linkage: LinkageConfig) -> FourBar:
        return cls(
            linkage.ground_m, linkage.crank_m, linkage.coupler_m, linkage.rocker_m, linkage.branch
        )

    # -- positions ---------------------------------------------------------------------------
    def _first_assembled(self) -> float:
        psi = np.linspace(0.0, 2.0 * math.pi, 721)
        ok = self._radicand(psi) >= 0.0
        if not ok.any():
            raise SimInputError(
                "link lengths", "make a linkage that cannot assemble at any crank angle"
            )
        return float(psi[np.argmax(ok)])

    def crank_tip_m(self, crank_angle_rad: ArrayLike) -> FloatArray:
        """P (Eq. 1), shape (..., 2) in (x, y)."""
        psi = np.asarray(crank_angle_rad, dtype=float)
        return np.stack([self.crank_m * np.cos(psi), self.crank_m * np.sin(psi)], axis=-1)

    def rocker_tip_m(self, crank_angle_rad: ArrayLike) -> FloatArray:
        """Q (Eq. 2), shape (..., 2) in (x, y)."""
        phi = self.rocker_angle_rad(crank_angle_rad)
        return np.stack(
            [self.ground_m + self.rocker_m * np.cos(phi), self.rocker_m * np.sin(phi)], axis=-1
        )

    def _radicand(self, psi: FloatArray) -> FloatArray:
        a1, a2, a3, a4 = self.ground_m, self.crank_m, self.coupler_m, self.rocker_m
        dx = a2 * np.cos(psi) - a1
        dy = a2 * np.sin(psi)
        r = np.hypot(dx, dy)
        # (2 a4 r)^2 - (a4^2 + r^2 - a3^2)^2 in product form: no cancellation.
        return ((a4 + r) ** 2 - a3 * a3) * (a3 * a3 - (a4 - r) ** 2)

    def _raw_rocker_angle(self, psi: FloatArray) -> FloatArray:
        a1, a2, a3, a4 = self.ground_m, self.crank_m, self.coupler_m, self.rocker_m
        dx = a2 * np.cos(psi) - a1
        dy = a2 * np.sin(psi)
        r2 = dx * dx + dy * dy
        rad = self._radicand(psi)
        bad = rad < -1e-14 * (a1 + a2 + a3 + a4) ** 4
        if np.any(bad):
            where = float(np.asarray(psi)[bad].ravel()[0])
            raise SimInputError(
                "crank_angle_rad",
                f"{where!r} rad is out of reach: the linkage cannot assemble there "
                "(coupler cannot reach the rocker)",
            )
        gamma = np.arctan2(np.sqrt(np.maximum(rad, 0.0)), a4 * a4 + r2 - a3 * a3)
        phi = np.arctan2(dy, dx) - self.branch * gamma
        # Continuous representation around the angle at the reference crank position.
        return self._ref_rad + np.mod(phi - self._ref_rad + math.pi, 2.0 * math.pi) - math.pi

    def rocker_angle_rad(self, crank_angle_rad: ArrayLike) -> FloatArray:
        """Rocker angle phi(psi) (rad), vectorised, continuous over a crank turn."""
        psi = np.asarray(crank_angle_rad, dtype=float)
        return self._raw_rocker_angle(psi)

    def coupler_angle_rad(self, crank_angle_rad: ArrayLike) -> FloatArray:
        """Direction of the coupler P -> Q (rad)."""
        psi = np.asarray(crank_angle_rad, dtype=float)
        pq = self.rocker_tip_m(psi) - self.crank_tip_m(psi)
        return np.arctan2(pq[..., 1], pq[..., 0])

    def loop_closure_residual_m(self, crank_angle_rad: ArrayLike) -> FloatArray:
        """|P - Q| - a3 (Eq. 4 as a length), m."""
        psi = np.asarray(crank_angle_rad, dtype=float)
        pq = self.rocker_tip_m(psi) - self.crank_tip_m(psi)
        return np.hypot(pq[..., 0], pq[..., 1]) - self.coupler_m

    # -- rates -------------------------------------------------------------------------------
    def rocker_rate_rad_s(
        self, crank_angle_rad: ArrayLike, crank_rate_rad_s: ArrayLike
    ) -> FloatArray:
        """d phi / dt for crank angle psi and crank rate psi_dot (analytic)."""
        psi = np.asarray(crank_angle_rad, dtype=float)
        w2 = np.asarray(crank_rate_rad_s, dtype=float)
        phi = self.rocker_angle_rad(psi)
        th3 = self.coupler_angle_rad(psi)
        return self.crank_m * w2 * np.sin(th3 - psi) / (self.rocker_m * np.sin(th3 - phi))

    def rocker_accel_rad_s2(
        self,
        crank_angle_rad: ArrayLike,
        crank_rate_rad_s: ArrayLike,
        crank_accel_rad_s2: ArrayLike = 0.0,
    ) -> FloatArray:
        """d^2 phi / dt^2 for crank angle, rate and acceleration (analytic)."""
        psi = np.asarray(crank_angle_rad, dtype=float)
        w2 = np.asarray(crank_rate_rad_s, dtype=float)
        al2 = np.asarray(crank_accel_rad_s2, dtype=float)
        a2, a3, a4 = self.crank_m, self.coupler_m, self.rocker_m
        phi = self.rocker_angle_rad(psi)
        th3 = self.coupler_angle_rad(psi)
        s34 = np.sin(th3 - phi)
        w4 = a2 * w2 * np.sin(th3 - psi) / (a4 * s34)
        w3 = a2 * w2 * np.sin(phi - psi) / (a3 * s34)
        # Acceleration loop equation dotted with the coupler direction.
        num = (
            a2 * al2 * np.sin(th3 - psi)
            - a2 * w2 * w2 * np.cos(psi - th3)
            - a3 * w3 * w3
            + a4 * w4 * w4 * np.cos(phi - th3)
        )
        return num / (a4 * s34)

    # -- extrema and transmission angle -------------------------------------------------------
    def extrema(self) -> RockerExtrema:
        """True rocker extrema: the two dead-centre positions (crank and coupler collinear,
        extended and folded), found in closed form."""
        a1, a2, a3, a4 = self.ground_m, self.crank_m, self.coupler_m, self.rocker_m
        crank_angles = []
        for dist, flip in ((a3 + a2, 0.0), (a3 - a2, math.pi)):
            c = (dist * dist - a1 * a1 - a4 * a4) / (2.0 * a1 * a4)
            candidates = []
            for sgn in (1.0, -1.0):
                phi = sgn * math.acos(max(-1.0, min(1.0, c)))
                qx, qy = a1 + a4 * math.cos(phi), a4 * math.sin(phi)
                psi = math.atan2(qy, qx) + flip
                err = abs(float(self.rocker_angle_rad(psi)) - phi)
                err = min(err, abs(err - 2.0 * math.pi))
                candidates.append((err, psi % (2.0 * math.pi)))
            crank_angles.append(min(candidates)[1])
        values = [float(self.rocker_angle_rad(p)) for p in crank_angles]
        i_min = int(np.argmin(values))
        i_max = 1 - i_min
        return RockerExtrema(
            rocker_min_rad=values[i_min],
            crank_at_min_rad=crank_angles[i_min],
            rocker_max_rad=values[i_max],
            crank_at_max_rad=crank_angles[i_max],
        )

    def transmission_angle_rad(self, crank_angle_rad: ArrayLike) -> FloatArray:
        """Angle between coupler and rocker, in [0, pi] (law of cosines on P, Q, O4)."""
        psi = np.asarray(crank_angle_rad, dtype=float)
        a1, a2, a3, a4 = self.ground_m, self.crank_m, self.coupler_m, self.rocker_m
        r2 = (a2 * np.cos(psi) - a1) ** 2 + (a2 * np.sin(psi)) ** 2
        return np.arccos(np.clip((a3 * a3 + a4 * a4 - r2) / (2.0 * a3 * a4), -1.0, 1.0))

    def transmission_angle_range_rad(self) -> tuple[float, float]:
        """(min, max) transmission angle over a crank turn (at psi = 0 and psi = pi, where
        |P - O4| is smallest and largest)."""
        mu = self.transmission_angle_rad(np.array([0.0, math.pi]))
        return float(mu.min()), float(mu.max())

    # -- the paper's printed forms, for the documented comparison -----------------------------
    def paper_eq8_rocker_angle_rad(self, crank_angle_rad: ArrayLike, sign: int = 1) -> FloatArray:
        """The paper's printed Eq. 8, phi = 2 atan((A +/- sqrt(A^2+B^2-C^2)) / (B + C)), as
        printed (for comparison; off by pi from Eq. 4, see the module docstring)."""
        psi = np.asarray(crank_angle_rad, dtype=float)
        a1, a2, a3, a4 = self.ground_m, self.crank_m, self.coupler_m, self.rocker_m
        a = np.sin(psi)
        b = np.cos(psi) - a1 / a2
        c = a1 * np.cos(psi) / a4 - (a1 * a1 + a2 * a2 - a3 * a3 + a4 * a4) / (2.0 * a2 * a4)
        return 2.0 * np.arctan((a + sign * np.sqrt(a * a + b * b - c * c)) / (b + c))


def paper_eq9_rocker_angle_rad(crank_angle_rad: ArrayLike) -> FloatArray:
    """The paper's Eq. 9 exactly as printed (the paper's links substituted into Eq. 8)."""
    psi = np.asarray(crank_angle_rad, dtype=float)
    c = np.cos(psi)
    return 2.0 * np.arctan(
        0.6
        * (4.0 * np.sin(psi) + 2.0 * np.sqrt(5056.0 - 2601.0 * c * c + 765.0 * c))
        / (99.0 * c + 125.0)
    )


def corrected_eq9_rocker_angle_rad(crank_angle_rad: ArrayLike) -> FloatArray:
    """Eq. 9 re-derived from Eq. 4 for the paper's links (branch +1): the correct numeric
    input/output equation that the printed Eq. 9 garbles."""
    psi = np.asarray(crank_angle_rad, dtype=float)
    c = np.cos(psi)
    return 2.0 * np.arctan(
        0.6
        * (4.0 * np.sqrt(5056.0 - 2601.0 * c * c + 765.0 * c) - 39.0 * np.sin(psi))
        / (99.0 * c + 125.0)
    )
