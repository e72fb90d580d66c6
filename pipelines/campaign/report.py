"""The campaign report: the frequency response across runs (markdown + PNG).

Tip amplitude and phase lag of the crank fundamental against the measured crank
frequency, one point per run from the images, the strains and the run's simulation, each
with its standard uncertainty as an error bar (2 sd), and a sweep's curve over them when
one is given. Figures are ``matplotlib.figure.Figure`` on the Agg canvas (no pyplot).
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import xarray as xr
from matplotlib.figure import Figure

from pipelines.atomic import atomic_path
from pipelines.campaign.summary import FITTED_DAMPING

REPORT_NAME = "campaign.md"
FIGURE_NAME = "campaign_response.png"
DAMPING_FIGURE_NAME = "campaign_damping.png"
_STYLE = {"image": ("o", "C0"), "strain": ("s", "C1"), "sim": ("^", "C2")}


def _plot(catalogue: xr.Dataset, sweep: xr.Dataset | None, path: Path) -> None:
    fig = Figure(figsize=(8, 6.5), layout="constrained")
    ax_amp, ax_lag = fig.subplots(2, 1, sharex=True)
    ok = catalogue["status"].values == "ok"
    f = catalogue["crank_frequency_hz"].values[ok]
    for src, (marker, colour) in _STYLE.items():
        p = f"tip_lateral_{src}"
        amp = catalogue[f"{p}_amplitude_m"].values[ok] * 1e3
        amp_sd = catalogue[f"{p}_amplitude_sd_m"].values[ok] * 1e3
        lag = np.degrees(catalogue[f"{p}_phase_lag_rad"].values[ok])
        lag_sd = np.degrees(catalogue[f"{p}_phase_lag_sd_rad"].values[ok])
        kw = {"fmt": marker, "color": colour, "capsize": 3, "label": f"runs: {src}"}
        ax_amp.errorbar(f, amp, yerr=2 * amp_sd, **kw)
        ax_lag.errorbar(f, lag, yerr=2 * lag_sd, **kw)
    if sweep is not None:
        for a1 in sweep["a1"].values:
            pt = sweep.sel(a1=a1)
            label = f"sweep, four-bar drive, a1 = {a1:g} s"
            ax_amp.plot(sweep["crank_hz"], pt["tip_lateral_amplitude_m"] * 1e3, "-", label=label)
            ax_lag.plot(
                sweep["crank_hz"], np.degrees(pt["tip_lateral_phase_lag_rad"]), "-", label=label
            )
    ax_amp.set_ylabel("tip lateral amplitude [mm]")
    ax_lag.set_ylabel("phase lag behind rocker [deg]")
    ax_lag.set_xlabel("crank frequency [Hz]")
    ax_amp.set_title("Tip response at the crank frequency (error bars: 2 sd)")
    ax_amp.legend(fontsize=8)
    for ax in (ax_amp, ax_lag):
        ax.grid(True, alpha=0.3)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)


def _fitted(catalogue: xr.Dataset) -> np.ndarray:
    """Which runs carry a fitted a1 (process --fit-damping)."""
    if "fitted_a1_s" not in catalogue:
        return np.zeros(catalogue.sizes["run"], bool)
    return np.isfinite(catalogue["fitted_a1_s"].values) & (catalogue["status"].values == "ok")


def _plot_damping(catalogue: xr.Dataset, path: Path) -> None:
    """Fitted a1 against the measured crank frequency, 95 % intervals as error bars."""
    fit = _fitted(catalogue)
    fig = Figure(figsize=(8, 4), layout="constrained")
    ax = fig.subplots()
    ax.errorbar(
        catalogue["crank_frequency_hz"].values[fit],
        catalogue["fitted_a1_s"].values[fit],
        yerr=catalogue["fitted_a1_ci95_s"].values[fit],
        fmt="o",
        color="C3",
        capsize=3,
        label="runs: fitted a1",
    )
    ax.set_xlabel("crank frequency [Hz]")
    ax.set_ylabel("fitted a1 [s]")
    ax.set_title("Damping fitted to each run (error bars: 95 % interval)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8)
    with atomic_path(path) as tmp:
        fig.savefig(tmp, format="png", dpi=110)


def _damping_lines(catalogue: xr.Dataset, out_dir: Path) -> list[str]:
    """The fitted damping per run, when the campaign ran with --fit-damping."""
    fit = _fitted(catalogue)
    if not fit.any():
        return []
    _plot_damping(catalogue, out_dir / DAMPING_FIGURE_NAME)
    lines = [
        "## Damping fitted to each run",
        "",
        "a1 fitted to the strains' and the image tip's crank harmonics (`process "
        "--fit-damping`), ± the half-width of its 95 % interval (the cycles' scatter; "
        "errors shared by every cycle, as the gauge factors, are not in it).",
        "",
        "| run | crank Hz | a1 s | a0 1/s |",
        "|---|---|---|---|",
    ]
    runs = catalogue["run"].values
    for i in np.flatnonzero(fit):
        r = {
            name: float(catalogue[name].values[i])
            for name in ("crank_frequency_hz", *FITTED_DAMPING)
        }
        a0 = f"{r['fitted_a0_per_s']:.4g}"
        a0 += (
            f" ± {r['fitted_a0_ci95_per_s']:.2g}"
            if math.isfinite(r["fitted_a0_ci95_per_s"])
            else " (held)"
        )
        lines.append(
            f"| {runs[i]} | {r['crank_frequency_hz']:.4f} | "
            f"{r['fitted_a1_s']:.5g} ± {r['fitted_a1_ci95_s']:.2g} | {a0} |"
        )
    return [*lines, "", f"![fitted a1 against crank frequency]({DAMPING_FIGURE_NAME})", ""]


def _fmt(value: float, sd: float, scale: float, digits: int) -> str:
    if not math.isfinite(value):
        return "n/a"
    return f"{value * scale:.{digits}f} ± {sd * scale:.{digits}f}"


def write_campaign_report(
    catalogue: xr.Dataset, out_dir: Path, *, sweep: xr.Dataset | None = None, title: str = ""
) -> Path:
    """Write ``out_dir/campaign.md`` and its figure; return the markdown's path."""
    fig_path = out_dir / FIGURE_NAME
    _plot(catalogue, sweep, fig_path)
    statuses = catalogue["status"].values
    lines = [
        f"# {title or 'beambench campaign'}",
        "",
        f"{catalogue.sizes['run']} runs, "
        f"{int(np.sum(statuses == 'ok'))} processed ok, "
        f"{int(np.sum(statuses == 'flagged'))} flagged (processed, but a result is missing or "
        f"may be wrong: see its status), {int(np.sum(statuses == 'failed'))} failed. "
        "Only the runs processed ok are plotted. Amplitude (mm) and phase "
        "lag behind the rocker angle (deg) of the tip's crank fundamental, ± one standard "
        "uncertainty, over the steady part of each run. The uncertainties are the fits' "
        "statistical ones (noise left in the residuals); systematic errors are not in them "
        "(the image method's ~0.05 mm, the strain reconstruction's three-mode basis, the "
        "simulation's 2 % tolerance): compare sources with those in mind.",
        "",
        "| run | crank Hz | image mm | strain mm | sim mm | image deg | strain deg | "
        "sim deg | image-sim RMS mm | status |",
        "|---|---|---|---|---|---|---|---|---|---|",
    ]
    for i, run in enumerate(catalogue["run"].values):
        r = {name: catalogue[name].values[i] for name in catalogue.data_vars}
        f_hz, f_sd = float(r["crank_frequency_hz"]), float(r["crank_frequency_sd_hz"])
        cells = [str(run), f"{f_hz:.5f} ± {f_sd:.1e}" if math.isfinite(f_hz) else "n/a"]
        for src in ("image", "strain", "sim"):
            p = f"tip_lateral_{src}"
            cells.append(_fmt(r[f"{p}_amplitude_m"], r[f"{p}_amplitude_sd_m"], 1e3, 2))
        for src in ("image", "strain", "sim"):
            p = f"tip_lateral_{src}"
            deg = 180 / math.pi
            cells.append(_fmt(r[f"{p}_phase_lag_rad"], r[f"{p}_phase_lag_sd_rad"], deg, 2))
        rms = float(r["tip_lateral_image_vs_sim_rms_m"])
        cells.append(f"{rms * 1e3:.3f}" if math.isfinite(rms) else "n/a")
        status = str(r["status"])
        if status != "ok":
            status += ": " + str(r["error"]).splitlines()[0][:80]
        cells.append(status)
        lines.append("| " + " | ".join(cells) + " |")
    lines += ["", f"![tip response against crank frequency]({FIGURE_NAME})", ""]
    lines += _damping_lines(catalogue, out_dir)
    if sweep is not None:
        lines.append(
            f"Curves: `beambench sweep` of the simulator on the exact four-bar drive "
            f"({sweep.attrs.get('sim_model', '')}, damping law "
            f"{sweep.attrs.get('damping_law', '')})."
        )
    md = out_dir / REPORT_NAME
    with atomic_path(md) as tmp:
        tmp.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return md
