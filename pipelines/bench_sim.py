"""``beambench bench sim``: simulator speed against error.

For each scene a converged reference is computed here, in the same process: the exact
finite elements (``fe-corot``) with more elements and a tight integrator tolerance than any
candidate; it is checked by a second reference at a 30x looser tolerance (their difference
is printed as the reference's own error). The table gives, per model and setting, the wall
time of the solve per simulated second and the maximum tip-lateral error over the last three
drive cycles (reciprocating) or the whole run (spin-up), absolute and relative to the
largest reference tip deflection in that window.
"""

from __future__ import annotations

import logging
import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from sim.beam import BeamProperties, spin_up_beam
from sim.config import BeamConfig, DampingConfig, DriveConfig
from sim.drives import SinusoidDrive, SpinUpDrive
from sim.fe import simulate_fe
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


@dataclass(frozen=True)
class Scene:
    name: str
    beam: BeamProperties
    drive: Any
    t_s: np.ndarray
    window: np.ndarray  # bool mask of the samples the error is taken over
    damping: tuple[float, float]


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
    from sim.modal import simulate_modal

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
        from sim.modal_nonlinear import simulate_modal_nonlinear

        return lambda s: simulate_modal_nonlinear(
            s.beam, s.drive, s.t_s, n_modes=n, a0_per_s=s.damping[0], a1_s=s.damping[1],
            rtol=rtol, atol=rtol * 1e-3,
        )  # fmt: skip

    def auto(tol: float) -> Callable[[Scene], SimResult]:
        from sim.auto import simulate_auto

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
            ("fe-corot", "2 elements, rtol 1e-8", fe("corot", 2, 1e-8)),
            ("fe-corot", "4 elements, rtol 1e-8", fe("corot", 4, 1e-8)),
            ("fe-flxdyn", "2 elements, rtol 1e-6", fe("flxdyn", 2, 1e-6)),
            ("fe-corot radau5", "5 elements, rtol 1e-4", fe("corot", 5, 1e-4, "radau5")),
            ("auto", "tol 1e-2", auto(1e-2)),
            ("auto", "tol 1e-4", auto(1e-4)),
        ]
    return out


def _reference(scene: Scene, quick: bool, rtol: float) -> SimResult:
    n = 4 if quick else 6
    return simulate_fe(
        scene.beam, scene.drive, scene.t_s, n_elements=n, a0_per_s=scene.damping[0],
        a1_s=scene.damping[1], rtol=rtol, atol=rtol * 1e-3,
    )  # fmt: skip


def _error(res: SimResult, ref: SimResult, window: np.ndarray) -> tuple[float, float]:
    err = float(np.max(np.abs(res.tip_lateral_m[window] - ref.tip_lateral_m[window])))
    return err, err / float(np.max(np.abs(ref.tip_lateral_m[window])))


def table(quick: bool) -> tuple[list[Row], dict[str, float]]:
    """Compute the rows and, per scene, the reference's own relative error estimate."""
    rows: list[Row] = []
    ref_err: dict[str, float] = {}
    for scene in _scenes(quick):
        # undamped spin-up: Radau must follow the stiff axial modes at tight tolerances,
        # so its reference is looser (and checked like the others)
        spin = scene.damping[1] == 0.0
        rtol_ref = 1e-7 if spin else 1e-9
        ref = _reference(scene, quick, rtol_ref)
        check = _reference(scene, quick, rtol_ref * 30.0)
        ref_err[scene.name] = _error(check, ref, scene.window)[1]
        duration = float(scene.t_s[-1] - scene.t_s[0])
        rows.append(
            Row(scene.name, "reference fe-corot", f"{ref.settings['n_elements']} elements, "
                f"rtol {rtol_ref:g}", ref.wall_time_s / duration, 0.0, 0.0)
        )  # fmt: skip
        for model, setting, run_model in _candidates(quick):
            res = run_model(scene)
            err, rel = _error(res, ref, scene.window)
            rows.append(Row(scene.name, model, setting, res.wall_time_s / duration, err, rel))
    return rows, ref_err


def run(quick: bool) -> int:
    """Print the speed-against-error table; returns the exit status."""
    rows, ref_err = table(quick)
    print("scene                 | model              | setting                | s per sim s "
          "| max tip error (m) | relative")  # fmt: skip
    print("-" * 104)
    for r in rows:
        print(
            f"{r.scene:21s} | {r.model:18s} | {r.setting:22s} | {r.wall_per_sim_s:11.4f} | "
            f"{r.max_error_m:17.3e} | {r.rel_error:.2e}"
        )
    for name, e in ref_err.items():
        print(f"reference check ({name}): 30x looser rtol changes it by {e:.1e} relative")
    try:
        import exudyn  # noqa: F401
    except ImportError:
        print("exudyn: not installed (optional peer), no side-by-side row")
    else:
        print("exudyn: installed, but its ANCF rows are not wired into this table yet")
    return 0
