"""``beambench bench sim``: simulator speed against error.

For each scene a converged reference is computed here, in the same process: the exact
finite elements (``fe-corot``) with more elements and a tight integrator tolerance than any
candidate; it is checked by a second reference at a 30x looser tolerance (their difference
is printed as the reference's own error). The undamped spin-ups' references are
Richardson extrapolations of radau5 runs on 24 and 32 elements (the tip converges as
h^4: measured on 6 to 40 elements), whose own spatial error is estimated from the
extrapolation of 16 and 24 elements and printed below the table. The table gives, per
model and setting, the wall time of the solve per simulated second and the maximum
tip-lateral error over the last three drive cycles (reciprocating) or the whole run
(spin-up), absolute and relative to the largest reference tip deflection in that window.
On the damped scene radau5 also runs at fixed steps (``fixed_step_s``, no error control), the
step chosen per mesh as Exudyn's rows choose theirs, with 3 stages (order 5) and with 5
(order 9, ``stages=5``: longer steps at equal error); those rows' errors are only the
measured ones (``auto`` picks fixed steps only for gauged runs, whose strains ask an
rtol of 5e-6 or tighter, with their time error measured; its rows here have no gauges).

If Exudyn is installed (the ``peers`` extra), its ANCF cable (:mod:`pipelines.bench.peers_exudyn`)
runs on the same scenes in the same process. Its damping is strain-rate (Kelvin-Voigt)
damping, not Eq. 28's ``a0 M + a1 K_T``, so on the damped scene its error is taken against a
reference of its own damping law (beambench's FE with that law, same elements and
tolerance as the main reference) and, in a column of its own, against the Eq. 28 reference;
the gap between the two laws is printed below the table.
"""

from __future__ import annotations

import dataclasses
import logging
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from sim.beam import BeamProperties, spin_up_beam
from sim.config import BeamConfig, DampingConfig, DriveConfig
from sim.drives import SinusoidDrive, SpinUpDrive
from sim.models.fe import simulate_fe
from sim.result import SimResult

logger = logging.getLogger(__name__)


@dataclass(frozen=True)
class Row:
    scene: str
    model: str
    setting: str
    wall_per_sim_s: float
    max_error_m: float
    rel_error: float
    rel_error_eq28: float = math.nan  # Exudyn rows on a damped scene: against Eq. 28


@dataclass(frozen=True)
class Scene:
    name: str
    beam: BeamProperties
    drive: Any
    t_s: np.ndarray
    window: np.ndarray  # bool mask of the samples the error is taken over
    damping: tuple[float, float]


#: The setting of the row that shows 1e-6 on the reciprocating scene.
_ROW_1E6 = "8 elements, rtol 1e-6"


def _scenes(quick: bool) -> list[Scene]:
    rig = BeamProperties.from_config(BeamConfig())
    drive_cfg, damp = DriveConfig(), DampingConfig()
    paper = SinusoidDrive(drive_cfg.paper_amplitude_rad, drive_cfg.paper_omega_rad_s)
    period = 2.0 * math.pi / drive_cfg.paper_omega_rad_s
    dur = 1.5 * period if quick else 5.0
    t = np.linspace(0.0, dur, int(dur * 200) + 1)
    window = t >= dur - (0.5 if quick else 3.0) * period
    scenes = [
        Scene("reciprocating", rig, paper, t, window, (damp.a0_per_s, damp.a1_s)),
    ]
    for omega in (4.0,) if quick else (4.0, 10.0):
        dur_s = 5.0 if quick else 20.0
        ts = np.linspace(0.0, dur_s, int(dur_s * 20) + 1)
        scenes.append(
            Scene(
                f"spin-up {omega:g} rad/s",
                spin_up_beam(),
                SpinUpDrive(omega),
                ts,
                np.ones(ts.size, bool),
                (0.0, 0.0),
            )
        )
    return scenes


def _candidates(quick: bool) -> list[tuple[str, str, Callable[[Scene], SimResult]]]:
    from sim.models.modal import simulate_modal

    def modal(n: int, rtol: float) -> Callable[[Scene], SimResult]:
        return lambda s: simulate_modal(
            s.beam, s.drive, s.t_s, n_modes=n, a0_per_s=s.damping[0], a1_s=s.damping[1],
            rtol=rtol, atol=rtol * 1e-3,
        )  # fmt: skip

    def fe(form: str, n: int, rtol: float, method: str = "auto") -> Callable[[Scene], SimResult]:
        atol = rtol if method == "radau5" else rtol * 1e-3
        return lambda s: simulate_fe(
            s.beam, s.drive, s.t_s, n_elements=n, formulation=form, a0_per_s=s.damping[0],
            a1_s=s.damping[1], rtol=rtol, atol=atol, method=method,
        )  # fmt: skip

    def modal_nl(n: int, rtol: float) -> Callable[[Scene], SimResult]:
        from sim.models.modal_nonlinear import simulate_modal_nonlinear

        return lambda s: simulate_modal_nonlinear(
            s.beam, s.drive, s.t_s, n_modes=n, a0_per_s=s.damping[0], a1_s=s.damping[1],
            rtol=rtol, atol=rtol * 1e-3,
        )  # fmt: skip

    def auto(tol: float) -> Callable[[Scene], SimResult]:
        from sim.models.model_choice import simulate_auto

        return lambda s: simulate_auto(
            s.beam, s.drive, s.t_s, tol=tol, a0_per_s=s.damping[0], a1_s=s.damping[1]
        )

    out = [
        ("modal", "4 modes, rtol 1e-6", modal(4, 1e-6)),
        ("modal-nonlinear", "4 modes, rtol 1e-6", modal_nl(4, 1e-6)),
        ("fe-corot", "2 elements, rtol 1e-6", fe("corot", 2, 1e-6)),
        ("fe-corot radau5", "3 elements, rtol 1e-4", fe("corot", 3, 1e-4, "radau5")),
        ("auto", "tol 1e-3", auto(1e-3)),
    ]
    if not quick:
        out += [
            ("modal", "6 modes, rtol 1e-9", modal(6, 1e-9)),
            # the 1e-6 row: against the 12-element reference (its own error printed below)
            ("fe-corot radau5", _ROW_1E6, fe("corot", 8, 1e-6, "radau5")),
            ("fe-corot radau5", "2 elements, rtol 3e-4", fe("corot", 2, 3e-4, "radau5")),
            ("fe-corot radau5", "2 elements, rtol 1e-4", fe("corot", 2, 1e-4, "radau5")),
            ("fe-corot radau5", "4 elements, rtol 1e-5", fe("corot", 4, 1e-5, "radau5")),
            ("fe-corot radau5", "6 elements, rtol 1e-6", fe("corot", 6, 1e-6, "radau5")),
            ("fe-corot", "2 elements, rtol 1e-8", fe("corot", 2, 1e-8)),
            ("fe-corot", "4 elements, rtol 1e-8", fe("corot", 4, 1e-8)),
            ("fe-flxdyn", "2 elements, rtol 1e-6", fe("flxdyn", 2, 1e-6)),
            ("fe-corot radau5", "5 elements, rtol 1e-4", fe("corot", 5, 1e-4, "radau5")),
            ("auto", "tol 1e-2", auto(1e-2)),
            ("auto", "tol 1e-4", auto(1e-4)),
        ]
    return out


def _spin_candidates(quick: bool) -> list[tuple[str, str, Callable[[Scene], SimResult]]]:
    """Finer rows for the undamped spin-ups only (their extrapolated references resolve
    errors down to ~1e-7; the damped scene's 12-element reference would not)."""
    if quick:
        return []

    def fe(n: int, rtol: float) -> Callable[[Scene], SimResult]:
        return lambda s: simulate_fe(
            s.beam, s.drive, s.t_s, n_elements=n, rtol=rtol, atol=rtol, method="radau5"
        )

    return [
        ("fe-corot radau5", "12 elements, rtol 1e-6", fe(12, 1e-6)),
        ("fe-corot radau5", "16 elements, rtol 1e-7", fe(16, 1e-7)),
        ("fe-corot radau5", "24 elements, rtol 1e-7", fe(24, 1e-7)),
    ]


#: fixed-step radau5 rows of the damped scene, (elements, step s, Newton's tolerance,
#: Radau IIA stages): the step as Exudyn's rows fix theirs, chosen where the time error
#: matches the mesh's spatial error (2 elements: 8e-5 spatial; at 3 stages Newton does not
#: converge above ~0.03 s). At 5 stages (order 9) 0.05 s leaves the spatial error alone
#: on every mesh (2, 3, 5, 7 elements: 7.8e-5, 1.6e-5, 2.7e-6, 1.0e-6 against the
#: 12-element reference); Newton's test there at 3e-5 or tighter (looser, the stages'
#: iteration error spoils the next step's predictor and Newton diverges)
_FIXED_STEPS = ((2, 0.025, 1e-4, 3), (2, 0.03, 1e-3, 3), (3, 0.025, 1e-4, 3), (5, 0.015, 1e-5, 3),
                (6, 0.015, 1e-6, 3), (8, 0.0125, 1e-6, 3), (2, 0.05, 3e-5, 5),
                (3, 0.05, 3e-5, 5), (5, 0.05, 1e-5, 5), (7, 0.05, 1e-6, 5))  # fmt: skip
_FIXED_STEPS_QUICK = ((2, 0.025, 1e-4, 3), (2, 0.05, 3e-5, 5))


def _damped_candidates(quick: bool) -> list[tuple[str, str, Callable[[Scene], SimResult]]]:
    """The fixed-step rows, for the damped (reciprocating) scene only: undamped spin-ups
    keep their fast modes, which a fixed step would have to resolve."""

    def fixed(n: int, h: float, tol: float, stages: int) -> Callable[[Scene], SimResult]:
        return lambda s: simulate_fe(
            s.beam, s.drive, s.t_s, n_elements=n, a0_per_s=s.damping[0], a1_s=s.damping[1],
            rtol=tol, atol=tol, method="radau5", fixed_step_s=h, stages=stages,
        )  # fmt: skip

    def setting(n: int, h: float, tol: float, stages: int) -> str:
        if stages == 3:
            return f"{n} el., fixed h {h:g}, tol {tol:g}"
        return f"{n} el., h {h:g}, {stages} stages, tol {tol:g}"

    return [
        ("fe-corot radau5", setting(n, h, tol, st), fixed(n, h, tol, st))
        for n, h, tol, st in (_FIXED_STEPS_QUICK if quick else _FIXED_STEPS)
    ]


def _reference_elements(scene: Scene, quick: bool) -> int:
    # damped full run: 12 elements, so that the 8-element row can show 1e-6 (the pair gives
    # the reference's own spatial error by Richardson, displacements converging as h^4)
    return 4 if quick else (12 if scene.damping[1] > 0.0 else 6)


#: meshes of the spin-up references (coarse, middle, fine): the fine pair is extrapolated,
#: the coarse pair's extrapolation estimates its error
_SPIN_MESHES = (16, 24, 32)
_SPIN_MESHES_QUICK = (4, 6, 8)
#: the tip's order of convergence in the element length (cubic Hermite elements):
#: measured on the 10 rad/s spin-up at rtol 1e-9, the 6 to 40-element runs' differences
#: fall as h^4 (the 6, 8, 12, 16, 24 and 32-element runs are 2.2e-4, 7.2e-5, 1.5e-5,
#: 5.2e-6, 1.2e-6 and 4.2e-7 of the tip from the 32/40 extrapolation; the 16/24 and 24/32
#: extrapolations differ by 1.5e-7, the 24/32 and 32/40 by 6e-8)
_SPATIAL_ORDER = 4.0


def _extrapolate(coarse: SimResult, fine: SimResult) -> np.ndarray:
    """Richardson: the tip history with the h^p term of two meshes cancelled."""
    ratio = (fine.settings["n_elements"] / coarse.settings["n_elements"]) ** _SPATIAL_ORDER
    return fine.tip_lateral_m + (fine.tip_lateral_m - coarse.tip_lateral_m) / (ratio - 1.0)


def _spin_reference(
    scene: Scene, quick: bool, rtol: float
) -> tuple[SimResult, SimResult, list[str]]:
    """An undamped spin-up's reference, its 30x-looser-tolerance check and notes.

    radau5 (rtol = atol) on three meshes; the reference is the Richardson extrapolation
    of the two finest (its ``settings['n_elements']`` is the finest). Its spatial error
    is estimated by the difference from the extrapolation of the two coarser meshes
    (an overestimate: that one's error is the larger); the check repeats the middle mesh
    at a 30x looser tolerance and adds its change to the reference, so their difference
    is the time integration's share (6 elements at rtol 1e-9 are 1.4e-9 of the tip from
    1e-10)."""
    meshes = _SPIN_MESHES_QUICK if quick else _SPIN_MESHES

    def run(n: int, tol: float) -> SimResult:
        return simulate_fe(
            scene.beam, scene.drive, scene.t_s, n_elements=n, rtol=tol, atol=tol,
            method="radau5",
        )  # fmt: skip

    c, m, f = (run(n, rtol) for n in meshes)
    ref_tip = _extrapolate(m, f)
    ref = dataclasses.replace(
        f,
        tip_lateral_m=ref_tip,
        wall_time_s=c.wall_time_s + m.wall_time_s + f.wall_time_s,
        settings={**f.settings, "richardson_meshes": f"{meshes[1]}/{meshes[2]}"},
    )
    loose = run(meshes[1], 30.0 * rtol)
    check = dataclasses.replace(f, tip_lateral_m=ref_tip + (loose.tip_lateral_m - m.tip_lateral_m))
    w = scene.window
    scale = float(np.max(np.abs(ref_tip[w])))
    spatial = float(np.max(np.abs(ref_tip[w] - _extrapolate(c, m)[w]))) / scale
    fine_alone = float(np.max(np.abs(ref_tip[w] - f.tip_lateral_m[w]))) / scale
    notes = [
        f"reference ({scene.name}): Richardson (h^{_SPATIAL_ORDER:g}) of {meshes[1]} and "
        f"{meshes[2]} elements, radau5 rtol = atol {rtol:g}; its spatial error by the "
        f"{meshes[0]}/{meshes[1]} extrapolation: {spatial:.1e} (the {meshes[2]}-element run "
        f"alone is {fine_alone:.1e} from it)"
    ]
    return ref, check, notes


def _reference(scene: Scene, quick: bool, rtol: float, n: int | None = None) -> SimResult:
    n = _reference_elements(scene, quick) if n is None else n
    return simulate_fe(
        scene.beam, scene.drive, scene.t_s, n_elements=n, a0_per_s=scene.damping[0],
        a1_s=scene.damping[1], rtol=rtol, atol=rtol * 1e-3,
    )  # fmt: skip


def _error(res: SimResult, ref: SimResult, window: np.ndarray) -> tuple[float, float]:
    err = float(np.max(np.abs(res.tip_lateral_m[window] - ref.tip_lateral_m[window])))
    return err, err / float(np.max(np.abs(ref.tip_lateral_m[window])))


def _exudyn_settings(scene: Scene, quick: bool) -> list[tuple[int, float]]:
    """(elements, step) of the Exudyn rows: steps divide the output interval."""
    if scene.damping[1] > 0.0:
        return (
            [(2, 0.005)]
            if quick
            else [(2, 0.005), (2, 0.0025), (4, 0.0025), (4, 0.001), (8, 0.0005)]
        )
    return [(4, 0.01)] if quick else [(4, 0.01), (8, 0.005), (16, 0.0025), (32, 0.00125)]


def _exudyn_rows(
    scene: Scene, quick: bool, ref: SimResult, rtol_ref: float, notes: list[str]
) -> list[Row]:
    """Exudyn's rows for one scene (errors against its own damping law's reference)."""
    from pipelines.bench.peers_exudyn import simulate_exudyn, simulate_fe_kelvin_voigt

    duration = float(scene.t_s[-1] - scene.t_s[0])
    own = ref
    damped = scene.damping[1] > 0.0
    if damped:
        n_own = 4 if quick else 8
        own = simulate_fe_kelvin_voigt(
            scene.beam, scene.drive, scene.t_s, n_elements=n_own, a1_s=scene.damping[1],
            rtol=rtol_ref, atol=rtol_ref * 1e-3,
        )  # fmt: skip
        gap = _error(own, ref, scene.window)[1]
        notes.append(
            f"damping law ({scene.name}): beambench's FE with Exudyn's strain-rate damping "
            f"(a1 EA, a1 EI, no a0; {n_own} el., rtol {rtol_ref:g}) differs from Eq. 28 by "
            f"{gap:.2e} of the tip; Exudyn's errors are taken against it"
        )
    rows = []
    for n, h in _exudyn_settings(scene, quick):
        res = simulate_exudyn(
            scene.beam, scene.drive, scene.t_s, n_elements=n, step_s=h, a1_s=scene.damping[1]
        )
        err, rel = _error(res, own, scene.window)
        eq28 = _error(res, ref, scene.window)[1] if damped else math.nan
        rows.append(
            Row(scene.name, "exudyn ANCF", f"{n} elements, h {h:g}",
                res.wall_time_s / duration, err, rel, eq28)
        )  # fmt: skip
    return rows


def table(quick: bool) -> tuple[list[Row], dict[str, float]]:
    """Compute the rows and, per scene, the reference's own relative error estimate."""
    rows, ref_err, _ = table_with_notes(quick)
    return rows, ref_err


def table_with_notes(quick: bool) -> tuple[list[Row], dict[str, float], list[str]]:
    """:func:`table` and the lines printed below it (reference checks, Exudyn)."""
    from pipelines.bench.peers_exudyn import available
    from pipelines.progress import Progress

    rows: list[Row] = []
    ref_err: dict[str, float] = {}
    notes: list[str] = []
    scenes = _scenes(quick)
    candidates = _candidates(quick)
    spin_only = _spin_candidates(quick)
    damped_only = _damped_candidates(quick)
    n_spin = sum(s.damping[1] == 0.0 for s in scenes)
    total = len(scenes) * (len(candidates) + 2) + n_spin * len(spin_only)
    bar = Progress("bench sim", total=total + (len(scenes) - n_spin) * len(damped_only))
    for scene in scenes:
        # undamped spin-up: radau5 on three meshes, extrapolated (6 elements at rtol 1e-7
        # had left ~2e-4 of spatial error at 10 rad/s, hiding every error below it)
        spin = scene.damping[1] == 0.0
        # damped: rtol 1e-10, since at 1e-9 the 12-element reference is itself 1.3e-6 off
        # (measured against 1e-10), too much for the 1e-6 row (1e-10 costs ~3 s per sim s)
        rtol_ref = 1e-9 if spin else 1e-10
        if spin:
            ref, check, spin_notes = _spin_reference(scene, quick, rtol_ref)
            notes += spin_notes
            bar.update(2)
        else:
            ref = _reference(scene, quick, rtol_ref)
            bar.update(1)
            check = _reference(scene, quick, rtol_ref * 30.0)
            bar.update(1)
        ref_err[scene.name] = _error(check, ref, scene.window)[1]
        duration = float(scene.t_s[-1] - scene.t_s[0])
        label = (
            f"Richardson {ref.settings['richardson_meshes']} el." if spin
            else f"{ref.settings['n_elements']} elements"
        )  # fmt: skip
        rows.append(
            Row(scene.name, "reference fe-corot", f"{label}, rtol {rtol_ref:g}",
                ref.wall_time_s / duration, 0.0, 0.0)
        )  # fmt: skip
        for model, setting, run_model in candidates + (spin_only if spin else damped_only):
            bar.update(1)
            res = run_model(scene)
            err, rel = _error(res, ref, scene.window)
            rows.append(Row(scene.name, model, setting, res.wall_time_s / duration, err, rel))
            if setting == _ROW_1E6 and ref.settings["n_elements"] == 12:
                # h^4: e12 = (e8 - e12) (8/12)^4 / (1 - (8/12)^4)
                r4 = (8.0 / 12.0) ** 4
                notes.append(
                    f"reference check ({scene.name}): spatial error of the 12-element "
                    f"reference by Richardson from the 8-element row: {rel * r4 / (1 - r4):.1e}"
                )
        if available():
            rows += _exudyn_rows(scene, quick, ref, rtol_ref, notes)
    bar.close()
    return rows, ref_err, notes


def run(quick: bool) -> int:
    """Print the speed-against-error table; returns the exit status."""
    from pipelines.bench.peers_exudyn import available

    rows, ref_err, notes = table_with_notes(quick)
    print("scene                 | model              | setting                        | "
          "s per sim s | max tip error (m) | relative | vs Eq. 28")  # fmt: skip
    print("-" * 123)
    for r in rows:
        eq28 = f"{r.rel_error_eq28:.2e}" if math.isfinite(r.rel_error_eq28) else ""
        print(
            f"{r.scene:21s} | {r.model:18s} | {r.setting:30s} | {r.wall_per_sim_s:11.4f} | "
            f"{r.max_error_m:17.3e} | {r.rel_error:.2e} | {eq28}"
        )
    for name, e in ref_err.items():
        print(f"reference check ({name}): 30x looser rtol changes it by {e:.1e} relative")
    for line in notes:
        print(line)
    if not available():
        print("exudyn: not installed (optional peer), no side-by-side row")
    return 0
