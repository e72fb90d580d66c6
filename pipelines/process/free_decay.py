"""Damping from a free decay in a run (§5.2.1).

The paper held the hub, deflected the tip, released it and matched the logarithmic
decrement of the strain at gauge 2 with a simulation whose a0 = a1 were adjusted. Here a
run is searched for such a stretch: the rocker still (its range over every 0.25 s window
below ``STILL_RANGE_RAD``) for at least ``MIN_DECAY_S``, with the gauge-2 strain
oscillating after a release. On that stretch:

- the log decrement delta of gauge 2 (:func:`sim.damping.log_decrement`), the damping
  ratio zeta = delta / sqrt(4 pi^2 + delta^2) and the damped frequency;
- equal coefficients a = a0 = a1 in closed form from the first mode (Eq. 37:
  zeta = a / (2 w) + a w / 2, w the undamped frequency w_d / sqrt(1 - zeta^2));
- and the paper's way, a simulated free decay whose gauge-2 decrement matches
  (:func:`sim.scenes.free_decay`): the two agree when the first mode dominates gauge 2.

The simulation of a free-decay run starts from the measured state at the release (the
modal amplitudes fitted to the four strains, at rest) with the identified coefficients.
"""

from __future__ import annotations

import logging
import math
from dataclasses import asdict, dataclass, replace

import numpy as np
from numpy.typing import NDArray

from pipelines.rig import Rig
from sim.result import SimResult

log = logging.getLogger(__name__)

FloatArray = NDArray[np.float64]

# A still hub: the crank-rocker moves at least ~0.2 rad in any 0.25 s (even at its dead
# centres, 1/2 theta'' t^2 with theta'' ~ 25 rad/s^2), the potentiometer's noise is
# ~0.3 mrad; 1 degree separates them with margin on both sides.
STILL_WINDOW_S = 0.25
STILL_RANGE_RAD = math.radians(1.0)
# At least ~10 cycles of the 3.7 Hz first mode for a decrement fitted over many peaks.
MIN_DECAY_S = 3.0
GAUGE_INDEX = 1  # gauge 2, as the paper


@dataclass(frozen=True)
class FreeDecay:
    """What a run's free decay says about the damping (times on the results' clock)."""

    start_s: float
    end_s: float
    release_s: float
    hub_angle_rad: float
    frequency_hz: float
    log_decrement: float
    damping_ratio: float
    a_closed_form: float
    a_simulated: float

    def as_attrs(self) -> dict[str, float]:
        """Global attributes for the results file (units in the names)."""
        names = {
            "start_s": "free_decay_start_s",
            "end_s": "free_decay_end_s",
            "release_s": "free_decay_release_s",
            "hub_angle_rad": "free_decay_hub_angle_rad",
            "frequency_hz": "free_decay_frequency_hz",
            "log_decrement": "free_decay_log_decrement",
            "damping_ratio": "free_decay_damping_ratio",
            "a_closed_form": "free_decay_a0_per_s_eq37",
            "a_simulated": "free_decay_a0_per_s_matched",
        }
        return {names[k]: float(v) for k, v in asdict(self).items()}


def still_stretch(t_s: FloatArray, rocker_rad: FloatArray) -> tuple[int, int] | None:
    """Index range [i0, i1) of the longest stretch where the hub stays still, or None
    when there is none of ``MIN_DECAY_S``."""
    t = np.asarray(t_s, float)
    r = np.asarray(rocker_rad, float)
    if t.size < 4:
        return None
    dt = float(np.median(np.diff(t)))
    w = max(2, round(STILL_WINDOW_S / dt))
    n_win = t.size // w
    if n_win < 1:
        return None
    blocks = r[: n_win * w].reshape(n_win, w)
    with np.errstate(invalid="ignore"):
        still = np.nanmax(blocks, axis=1) - np.nanmin(blocks, axis=1) < STILL_RANGE_RAD
    best: tuple[int, int] | None = None
    k = 0
    while k < n_win:
        if not still[k]:
            k += 1
            continue
        j = k
        while j < n_win and still[j]:
            j += 1
        if best is None or j - k > best[1] - best[0]:
            best = (k, j)
        k = j
    if best is None:
        return None
    i0, i1 = best[0] * w, min(best[1] * w, t.size)
    if t[i1 - 1] - t[i0] < MIN_DECAY_S:
        return None
    return i0, i1


def _dominant_frequency_hz(t: FloatArray, y: FloatArray) -> float:
    dt = float(np.median(np.diff(t)))
    n_fft = 1 << int(np.ceil(np.log2(16 * y.size)))
    spectrum = np.abs(np.fft.rfft((y - y.mean()) * np.hanning(y.size), n_fft))
    k = int(np.argmax(spectrum[1:])) + 1
    # parabolic interpolation of the log spectrum around the peak
    if 1 <= k < spectrum.size - 1:
        a, b, c = np.log(spectrum[k - 1 : k + 2] + 1e-300)
        k_f = k + 0.5 * (a - c) / (a - 2 * b + c)
    else:
        k_f = float(k)
    return float(k_f / (n_fft * dt))


def _release_time(t: FloatArray, y: FloatArray, k_rel: int, n0: int, w_rad_s: float) -> float:
    """The release instant, finer than the first sample that moved: released from rest,
    the strain leaves its held level y_h towards equilibrium y_e as
    (y_h - y_e) cos(w (t - t_r)), so each early sample gives t_r = t - arccos(1 - d) / w
    with d the fraction of the way travelled."""
    held = float(np.median(y[:n0])) if k_rel >= n0 else float(y[k_rel])
    eq = float(np.median(y[-max(4, y.size // 4) :]))
    amp = held - eq
    if amp == 0.0:
        return float(t[k_rel])
    d = (held - y[k_rel:]) / amp
    first_swing = np.flatnonzero(d > 0.6)
    stop = int(first_swing[0]) if first_swing.size else d.size
    use = np.flatnonzero((d[:stop] > 0.02) & (d[:stop] < 0.5))
    if use.size == 0:
        return float(t[k_rel])
    t_r = t[k_rel:][use] - np.arccos(1.0 - d[use]) / w_rad_s
    return float(np.median(t_r))


def find_free_decay(
    rig: Rig, t_s: FloatArray, rocker_rad: FloatArray, strain: FloatArray
) -> FreeDecay | None:
    """The run's free decay, identified; None when the run has none (a reciprocating
    run) or the still stretch does not oscillate measurably."""
    from sim.damping import damping_ratio_from_log_decrement, log_decrement
    from sim.scenes import free_decay

    span = still_stretch(t_s, rocker_rad)
    if span is None:
        return None
    i0, i1 = span
    t = np.asarray(t_s, float)[i0:i1]
    y = np.asarray(strain, float)[i0:i1, GAUGE_INDEX]
    good = np.isfinite(y)
    t, y = t[good], y[good]
    if t.size < 16:
        return None
    # the release: where the strain leaves the level it was held at (the first 0.1 s)
    d2 = np.diff(y, 2)
    noise = float(np.median(np.abs(d2 - np.median(d2)))) / 0.6745 / math.sqrt(6.0)
    n0 = max(3, int(0.1 / float(np.median(np.diff(t)))))
    dev = np.abs(y - float(np.median(y[:n0])))
    away = np.flatnonzero(dev > max(10.0 * noise, 0.05 * float(np.max(dev))))
    k_rel = int(away[0]) if away.size else 0
    # back to the last sample still at the held level
    while k_rel > 0 and dev[k_rel - 1] > 3.0 * noise:
        k_rel -= 1
    t_d, y_d = t[k_rel:], y[k_rel:]
    if t_d[-1] - t_d[0] < MIN_DECAY_S:
        return None
    try:
        delta = log_decrement(t_d, y_d, min_peaks=6)
    except ValueError as exc:
        log.info("still hub from %.1f s but no measurable decay: %s", t[0], exc)
        return None
    if not 0.0 < delta < 2.0:
        return None
    zeta = damping_ratio_from_log_decrement(delta)
    f_d = _dominant_frequency_hz(t_d, y_d)
    w = 2.0 * math.pi * f_d / math.sqrt(1.0 - zeta**2)
    t_release = _release_time(t, y, k_rel, n0, w)
    a_closed = 2.0 * zeta / (1.0 / w + w)
    matched = free_decay(
        rig.beam,
        rig.damping,
        gauge_positions_m=rig.gauges.positions_m,
        target_log_decrement=delta,
        duration_s=min(float(t_d[-1] - t_d[0]), 20.0),
    )
    return FreeDecay(
        start_s=float(t[0]),
        end_s=float(t[-1]),
        release_s=t_release,
        hub_angle_rad=float(np.nanmedian(np.asarray(rocker_rad, float)[i0:i1])),
        frequency_hz=f_d,
        log_decrement=float(delta),
        damping_ratio=float(zeta),
        a_closed_form=float(a_closed),
        a_simulated=float(matched.extras["identified_a0_per_s"]),
    )


def simulate_release(
    rig: Rig, t_s: FloatArray, strain: FloatArray, decay: FreeDecay, *, n_modes: int = 3
) -> SimResult:
    """The beam released at ``decay.release_s`` from the measured strains (modal
    amplitudes fitted to the gauges, averaged over the held 0.2 s before, at rest),
    damped with the matched a0 = a1, on the whole run's ``t_s``; before the release the
    held shape."""
    from sim.beam import BeamProperties
    from sim.drives import FixedDrive
    from sim.models.modal import simulate_modal
    from sim.modes import mode_shapes

    beam = BeamProperties.from_config(rig.beam)
    t = np.asarray(t_s, float)
    eps = np.asarray(strain, float)
    gauges = np.asarray(rig.gauges.positions_m, float)
    k_rel = int(np.searchsorted(t, decay.release_s, side="right"))  # first moving sample
    held = (t >= decay.release_s - 0.2) & (t <= decay.release_s)
    eps0 = np.nanmean(eps[held], axis=0) if held.any() else eps[min(k_rel, t.size - 1)]
    # strain = -(t/2) w'' at the gauges (no axial strain with the hub still)
    phi2 = mode_shapes(gauges, beam.length_m, n_modes, derivative=2)
    q0, *_ = np.linalg.lstsq(-beam.surface_offset_m * phi2, eps0, rcond=None)
    a = decay.a_simulated
    after = simulate_modal(
        beam,
        FixedDrive(decay.hub_angle_rad),
        np.concatenate([[decay.release_s], t[k_rel:]]),
        n_modes=n_modes,
        a0_per_s=a,
        a1_s=a,
        gauge_positions_m=gauges,
        initial_q=q0,
        rtol=1e-8,
        atol=1e-12,
    )

    # the release state held until then; the release instant itself is not on the grid
    whole = after.held_before(t[:k_rel])
    whole = whole.rows(np.r_[0:k_rel, k_rel + 1 : whole.time_s.size])
    return replace(
        whole,
        model=f"{after.model} (free decay from the measured release)",
        wall_time_s=after.wall_time_s,
        settings={**after.settings, "release_s": decay.release_s, "a0_per_s": a, "a1_s": a},
    )
