"""The plots of ``beambench reproduce`` (PNG through matplotlib's Agg canvas, no pyplot).

Each function takes the numbers a section of :mod:`pipelines.reproduce.report` computed and a
path; angles arrive in degrees and lengths in mm (the report's units), as the argument
names say.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure
from numpy.typing import NDArray

FloatArray = NDArray[np.float64]


def _save(fig: Figure, path: Path) -> None:
    # The report is written into a fresh temporary folder and renamed as a whole, so
    # the plots need no temporary names of their own.
    fig.savefig(path, format="png", dpi=100)


def plot_four_bar(
    path: Path,
    crank_deg: FloatArray,
    curves_deg: Mapping[str, FloatArray],
    true_extrema_deg: Sequence[tuple[float, float]],
    paper_extrema_deg: Sequence[tuple[float, float]],
    transmission_deg: FloatArray,
) -> None:
    """Rocker angle against crank angle (true and the paper's printed forms), with the
    extrema, and the transmission angle below."""
    fig = Figure(figsize=(8, 6.5), layout="constrained")
    top, bottom = fig.subplots(2, 1, sharex=True, height_ratios=[3, 1.3])
    for label, y in curves_deg.items():
        style = "k-" if label.startswith("Eq. 4") else "--"
        top.plot(crank_deg, y, style, lw=1.2 if style == "k-" else 0.9, label=label)
    top.plot(*zip(*true_extrema_deg, strict=True), "o", ms=7, label="true extrema (dead centres)")
    top.plot(*zip(*paper_extrema_deg, strict=True), "x", ms=9, mew=2, label="paper Eqs. 10-11")
    top.set_ylabel("rocker angle (deg)")
    top.set_title("Four-bar input/output, frame of Eqs. 1-2", fontsize=10)
    top.grid(alpha=0.3)
    top.legend(fontsize=8, loc="lower center")
    bottom.plot(crank_deg, transmission_deg, "k-", lw=1.0)
    bottom.set_ylabel("transmission\nangle (deg)")
    bottom.set_xlabel("crank angle (deg)")
    bottom.grid(alpha=0.3)
    _save(fig, path)


def plot_hub_drives(
    path: Path,
    t_s: FloatArray,
    angle_deg: Mapping[str, FloatArray],
    accel_rad_s2: Mapping[str, FloatArray],
) -> None:
    """Hub angle and hub acceleration over one cycle for each drive."""
    fig = Figure(figsize=(8, 5.5), layout="constrained")
    top, bottom = fig.subplots(2, 1, sharex=True)
    for label, y in angle_deg.items():
        top.plot(t_s, y, lw=1.0, label=label)
    for label, y in accel_rad_s2.items():
        bottom.plot(t_s, y, lw=1.0, label=label)
    top.set_ylabel("hub angle about\nmid-stroke (deg)")
    bottom.set_ylabel("hub acceleration\n(rad/s²)")
    bottom.set_xlabel("time (s)")
    top.set_title("The paper's sinusoid (Eq. 53) and the four-bar at the same crank speed")
    for ax in (top, bottom):
        ax.grid(alpha=0.3)
        ax.legend(fontsize=8)
    _save(fig, path)


def plot_table2(
    path: Path, mass_kg: FloatArray, tip_mm: Mapping[str, FloatArray], mark: Sequence[str]
) -> None:
    """Tip deflection per unit mass against tip mass for each row of the comparison
    (per kg, so a linear model is a flat line and the differences show)."""
    fig = Figure(figsize=(7.5, 4.5), layout="constrained")
    ax = fig.subplots()
    for label, y in tip_mm.items():
        style = "o-" if label in mark else "s--"
        ax.plot(mass_kg, np.asarray(y) / mass_kg, style, ms=5, lw=1.0, label=label)
    ax.set_xlabel("tip mass (kg)")
    ax.set_ylabel("tip deflection per tip mass (mm/kg)")
    ax.set_title("Table 2: static tip deflection, paper and beambench", fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="best")
    _save(fig, path)


def plot_damping_ratios(
    path: Path,
    omega_rad_s: FloatArray,
    curves: Mapping[str, FloatArray],
    modes_rad_s: FloatArray,
) -> None:
    """Modal damping ratio (Eq. 37) against frequency, natural frequencies marked."""
    fig = Figure(figsize=(7, 4), layout="constrained")
    ax = fig.subplots()
    for label, z in curves.items():
        ax.loglog(omega_rad_s, z, lw=1.2, label=label)
    for k, w in enumerate(modes_rad_s, start=1):
        ax.axvline(w, color="0.6", lw=0.8, ls=":")
        ax.text(w, ax.get_ylim()[0] * 1.5, f" {k}", fontsize=8, color="0.4")
    ax.axhline(1.0, color="r", lw=0.8, ls="--", label="critical damping")
    ax.set_xlabel("natural frequency (rad/s); dotted: bending modes 1-5")
    ax.set_ylabel("damping ratio (Eq. 37)")
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    _save(fig, path)


def plot_free_decay(
    path: Path, t_s: FloatArray, strain_micro: FloatArray, envelope_micro: FloatArray
) -> None:
    """The simulated free decay at gauge 2 with the envelope of the identified decrement."""
    fig = Figure(figsize=(8, 3.5), layout="constrained")
    ax = fig.subplots()
    ax.plot(t_s, strain_micro, lw=0.6, label="gauge 2, simulated release (a0 = a1 = 0.00087)")
    ax.plot(t_s, envelope_micro, "r--", lw=1.0, label="envelope of the measured log decrement")
    ax.plot(t_s, -envelope_micro, "r--", lw=1.0)
    ax.set_xlabel("time after release (s)")
    ax.set_ylabel("strain (µε)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8, loc="upper right")
    _save(fig, path)


def plot_fig10(path: Path, paths_mm: Mapping[str, tuple[FloatArray, FloatArray]]) -> None:
    """Tip paths: per drive (flexible x, y) and (rigid x, y), in mm, pivot at the origin,
    x along the beam at mid-stroke."""
    fig = Figure(figsize=(11, 4.8), layout="constrained")
    axes = fig.subplots(1, len(paths_mm), squeeze=False)[0]
    for ax, (label, (flex, rigid)) in zip(axes, paths_mm.items(), strict=True):
        ax.plot(rigid[:, 0], rigid[:, 1], color="0.7", lw=3, label="rigid beam")
        ax.plot(flex[:, 0], flex[:, 1], "k-", lw=0.9, label="flexible beam")
        ax.set_aspect("equal", adjustable="datalim")
        ax.set_title(label, fontsize=9)
        ax.set_xlabel("x along mid-stroke (mm)")
        ax.grid(alpha=0.3)
    axes[0].set_ylabel("y (mm)")
    axes[0].legend(fontsize=8, loc="lower left")
    fig.suptitle("Fig. 10: simulated tip paths, last three cycles", fontsize=10)
    _save(fig, path)


def plot_fig11(path: Path, loops: Mapping[str, tuple[FloatArray, FloatArray]]) -> None:
    """Lateral tip deflection (mm) against hub angle about mid-stroke (deg), per drive."""
    fig = Figure(figsize=(7.5, 4.8), layout="constrained")
    ax = fig.subplots()
    for label, (angle_deg, tip_mm) in loops.items():
        ax.plot(angle_deg, tip_mm, lw=1.0, label=label)
    ax.set_xlabel("input (hub) angle about mid-stroke (deg)")
    ax.set_ylabel("lateral tip deflection (mm)")
    ax.set_title("Fig. 11: steady state, three cycles per drive (modal, a0 = a1 = 0.1)")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    _save(fig, path)


def plot_spin_up(path: Path, t_s: FloatArray, tip_m: Mapping[str, FloatArray]) -> None:
    """|tip deflection| of the spin-up beam on a log scale (the unstiffened model diverges)."""
    fig = Figure(figsize=(8, 4), layout="constrained")
    ax = fig.subplots()
    for label, y in tip_m.items():
        ax.semilogy(t_s, np.abs(y), lw=1.0, label=label)
    ax.set_ylim(1e-4, 1e3)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("|lateral tip deflection| (m)")
    ax.set_title("Spin-up beam (L = 10 m), with and without geometric stiffening", fontsize=10)
    ax.grid(alpha=0.3, which="both")
    ax.legend(fontsize=8)
    _save(fig, path)
