"""Modal against finite elements on the reciprocating scene (a study script).

    .venv/bin/python benchmarks/study_modal_vs_fe.py

Rig beam, paper drive (Eq. 53) at full, half and quarter stroke, a0 = a1 = 0.1, 4 s from
rest at 400 Hz; the maximum tip difference over the last two cycles relative to the
largest tip deflection there, for the linear modal model (6 modes, damping with the
tangent K_T and with the elastic K), the third-order modal model, and sim.models.fe's 'corot'
beam (4 elements). Slow: the finite elements take about a minute per run.
"""

from __future__ import annotations

import numpy as np

from sim.beam import BeamProperties
from sim.config import BeamConfig
from sim.drives import SinusoidDrive
from sim.models.fe import simulate_fe
from sim.models.modal import simulate_modal
from sim.models.modal_nonlinear import simulate_modal_nonlinear


def main() -> None:
    beam = BeamProperties.from_config(BeamConfig())
    t = np.arange(0.0, 4.0 + 1e-9, 1.0 / 400.0)
    window = t > t[-1] - 2 * 2 * np.pi / 4.970
    kw = {"a0_per_s": 0.1, "a1_s": 0.1}
    print(f"{'stroke':>7} {'tip mm':>8} {'modal K_T':>10} {'modal K':>9} {'modal-nl':>9}")
    for scale in (1.0, 0.5, 0.25):
        drive = SinusoidDrive(0.7669 * scale, 4.970)
        fe = simulate_fe(beam, drive, t, n_elements=4, rtol=1e-8, atol=1e-12, **kw)  # type: ignore[arg-type]
        ref = fe.tip_lateral_m[window]
        size = np.abs(ref).max()
        row = []
        for res in (
            simulate_modal(beam, drive, t, n_modes=6, rtol=1e-9, **kw),  # type: ignore[arg-type]
            simulate_modal(beam, drive, t, n_modes=6, rtol=1e-9, damping_geometric=False, **kw),  # type: ignore[arg-type]
            simulate_modal_nonlinear(beam, drive, t, n_modes=6, rtol=1e-9, **kw),  # type: ignore[arg-type]
        ):
            row.append(np.abs(res.tip_lateral_m[window] - ref).max() / size)
        print(f"{scale:>7.2f} {size * 1e3:>8.3f} {row[0]:>10.2e} {row[1]:>9.2e} {row[2]:>9.2e}")


if __name__ == "__main__":
    main()
