"""Configuration of the simulated bench: linkage, beam, damping and drive.

Frozen dataclasses validated on construction. Values are SI; every field name
carries its unit. A bad value raises ``ValueError`` whose message starts with
the field name, so a loader can point at the offending key.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from sim.errors import SimInputError


def _positive(name: str, value: float) -> None:
    if not math.isfinite(value) or value <= 0.0:
        raise SimInputError(name, f"must be a positive finite number, got {value!r}")


def _non_negative(name: str, value: float) -> None:
    if not math.isfinite(value) or value < 0.0:
        raise SimInputError(name, f"must be a non-negative finite number, got {value!r}")


def _at_most(name: str, value: float, limit: float, unit: str, why: str) -> None:
    """Refuse a (finite, signed-checked) value above a physical limit, saying why."""
    if not abs(value) <= limit:
        raise SimInputError(name, f"must be at most {limit:g} {unit} ({why}), got {value!r}")


# Physical limits of a bench this software models (each states its reason in the error).
MAX_LINK_M = 10.0  # a laboratory linkage
MAX_CRANK_HZ = 20.0  # a bench motor; five times the beam's first mode
MAX_BEAM_M = 10.0  # a laboratory beam
MAX_SECTION_M = 0.5  # width and thickness of a slender beam
YOUNGS_RANGE_PA = (1e5, 1.5e12)  # soft rubber to diamond
DENSITY_RANGE_KG_M3 = (10.0, 25000.0)  # foams to osmium
MAX_A0_PER_S = 1e3  # mass-proportional damping: a mode decays in 2 ms at most
MAX_A1_S = 10.0  # stiffness-proportional damping, s
MAX_DRIVE_OMEGA_RAD_S = 200.0  # a bench motor's hub motion (32 Hz)


@dataclass(frozen=True)
class LinkageConfig:
    """Planar four-bar of paper §2.1 (Eqs. 1-4): a1 ground, a2 crank, a3 coupler, a4 rocker.

    ``branch`` is +1 for the elbow-up assembly (positive radicand of Eq. 8), -1 for
    elbow-down. ``beam_mount_angle_rad`` is the angle of the beam axis (pivot towards
    the free end) relative to the rocker direction, so that the hub angle in the
    mechanism frame of Eqs. 1-2 is ``rocker_angle + beam_mount_angle_rad``.
    """

    ground_m: float = 0.340
    crank_m: float = 0.045
    coupler_m: float = 0.330
    rocker_m: float = 0.065
    branch: int = 1
    crank_frequency_hz: float = 0.92
    beam_mount_angle_rad: float = math.pi

    def __post_init__(self) -> None:
        for name in ("ground_m", "crank_m", "coupler_m", "rocker_m", "crank_frequency_hz"):
            _positive(name, getattr(self, name))
        for name in ("ground_m", "crank_m", "coupler_m", "rocker_m"):
            _at_most(name, getattr(self, name), MAX_LINK_M, "m", "a laboratory linkage")
        _at_most("crank_frequency_hz", self.crank_frequency_hz, MAX_CRANK_HZ, "Hz", "a bench motor")
        if self.branch not in (1, -1):
            raise SimInputError(
                "branch", f"must be 1 (elbow up) or -1 (elbow down), got {self.branch!r}"
            )
        if not abs(self.beam_mount_angle_rad) <= 2.0 * math.pi:
            raise SimInputError(
                "beam_mount_angle_rad",
                f"must be finite and within +/-2 pi (one turn), got {self.beam_mount_angle_rad!r}",
            )
        lengths = sorted((self.ground_m, self.crank_m, self.coupler_m, self.rocker_m))
        s, p, q, l = lengths
        if s + l > p + q:
            raise SimInputError(
                "crank_m",
                "cannot turn: the linkage is not Grashof "
                f"(shortest + longest = {s + l:.6g} m > sum of the others = {p + q:.6g} m), "
                "so no link can rotate fully and the crank cannot drive the rocker",
            )
        if self.crank_m != s:
            raise SimInputError(
                "crank_m",
                f"must be the shortest link for a crank-rocker; "
                f"crank = {self.crank_m!r} m, shortest = {s!r} m",
            )


@dataclass(frozen=True)
class BeamConfig:
    """The aluminium beam (paper Tables 1 and 3).

    Bending is across ``thickness_m`` (in the plane of the mechanism). ``length_m`` is
    clamp to free end; ``hub_offset_m`` is pivot to clamp (rigid hub).
    ``second_moment_m4`` must agree with width * thickness**3 / 12 to 0.1 %.
    """

    length_m: float = 0.835
    hub_offset_m: float = 0.008
    width_m: float = 0.01905
    thickness_m: float = 0.003175
    youngs_modulus_pa: float = 6.89e10
    density_kg_m3: float = 2688.2
    second_moment_m4: float = 5.08095e-11

    def __post_init__(self) -> None:
        for name in (
            "length_m",
            "width_m",
            "thickness_m",
            "youngs_modulus_pa",
            "density_kg_m3",
            "second_moment_m4",
        ):
            _positive(name, getattr(self, name))
        _non_negative("hub_offset_m", self.hub_offset_m)
        _at_most("length_m", self.length_m, MAX_BEAM_M, "m", "a laboratory beam")
        for name in ("width_m", "thickness_m"):
            _at_most(name, getattr(self, name), MAX_SECTION_M, "m", "a slender beam")
        if self.hub_offset_m >= self.length_m:
            raise SimInputError(
                "hub_offset_m",
                f"({self.hub_offset_m!r} m, pivot to clamp) must be shorter than the beam "
                f"(length_m {self.length_m!r} m)",
            )
        lo, hi = YOUNGS_RANGE_PA
        if not lo <= self.youngs_modulus_pa <= hi:
            raise SimInputError(
                "youngs_modulus_pa",
                f"must be within {lo:g}..{hi:g} Pa (soft rubber to diamond), "
                f"got {self.youngs_modulus_pa!r}",
            )
        lo, hi = DENSITY_RANGE_KG_M3
        if not lo <= self.density_kg_m3 <= hi:
            raise SimInputError(
                "density_kg_m3",
                f"must be within {lo:g}..{hi:g} kg/m^3 (foam to osmium), "
                f"got {self.density_kg_m3!r}",
            )
        if self.thickness_m >= self.width_m:
            raise SimInputError(
                "thickness_m",
                f"({self.thickness_m!r}) must be smaller than width_m ({self.width_m!r}): "
                "the beam bends across its thickness",
            )
        expected = self.width_m * self.thickness_m**3 / 12.0
        if abs(self.second_moment_m4 - expected) > 1e-3 * expected:
            raise SimInputError(
                "second_moment_m4",
                f"= {self.second_moment_m4:.6g} m^4 disagrees with "
                f"width_m * thickness_m**3 / 12 = {expected:.6g} m^4",
            )

    @property
    def area_m2(self) -> float:
        return self.width_m * self.thickness_m

    @property
    def mass_per_length_kg_m(self) -> float:
        return self.density_kg_m3 * self.area_m2

    @property
    def bending_stiffness_n_m2(self) -> float:
        return self.youngs_modulus_pa * self.second_moment_m4

    @property
    def axial_stiffness_n(self) -> float:
        return self.youngs_modulus_pa * self.area_m2

    @property
    def surface_offset_m(self) -> float:
        """Distance z from the neutral axis to the gauged surface (t/2, Eq. 50)."""
        return 0.5 * self.thickness_m

    @property
    def pivot_to_tip_m(self) -> float:
        return self.hub_offset_m + self.length_m


#: the damping laws: ``"paper"``, Eq. 28's a0 M + a1 K_T with K_T the tangent stiffness
#: (geometric stiffness of the current axial force and moment included, FLXDYN's form), and
#: ``"material"``, Kelvin-Voigt: a0 M on the elastic rates plus a1 times the material
#: stiffness acting on the strain rates (bending and axial), the law of most codes (Exudyn)
DAMPING_LAWS = ("paper", "material")


@dataclass(frozen=True)
class DampingConfig:
    """Proportional damping F = (a0 M + a1 K) * relative nodal velocities (Eq. 28).

    ``a0_per_s``/``a1_s`` are the reciprocating-run values; the ``free_decay_*`` pair is
    the one the paper fitted from the free-decay test (§5.2.1). ``law`` (one of
    :data:`DAMPING_LAWS`) says which K: the tangent stiffness (``"paper"``) or the
    material stiffness on the strain rates (``"material"``).
    """

    a0_per_s: float = 0.1
    a1_s: float = 0.1
    free_decay_a0_per_s: float = 0.00087
    free_decay_a1_s: float = 0.00087
    law: str = "paper"

    def __post_init__(self) -> None:
        for name in ("a0_per_s", "a1_s", "free_decay_a0_per_s", "free_decay_a1_s"):
            _non_negative(name, getattr(self, name))
        if self.law not in DAMPING_LAWS:
            raise SimInputError(
                "law", f"must be one of {', '.join(DAMPING_LAWS)}, got {self.law!r}"
            )
        for name in ("a0_per_s", "free_decay_a0_per_s"):
            _at_most(name, getattr(self, name), MAX_A0_PER_S, "1/s", "a mode decays in 2 ms")
        for name in ("a1_s", "free_decay_a1_s"):
            _at_most(name, getattr(self, name), MAX_A1_S, "s", "stiffness-proportional")


@dataclass(frozen=True)
class DriveConfig:
    """The paper's prescribed hub motion, Phi = A sin(w t) about mid-stroke (Eq. 53)."""

    paper_amplitude_rad: float = 0.7669
    paper_omega_rad_s: float = 4.970

    def __post_init__(self) -> None:
        _positive("paper_amplitude_rad", self.paper_amplitude_rad)
        _positive("paper_omega_rad_s", self.paper_omega_rad_s)
        _at_most("paper_amplitude_rad", self.paper_amplitude_rad, math.pi, "rad", "half a turn")
        _at_most(
            "paper_omega_rad_s",
            self.paper_omega_rad_s,
            MAX_DRIVE_OMEGA_RAD_S,
            "rad/s",
            "a bench motor",
        )
