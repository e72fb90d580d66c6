"""The background under a smeared beam's cuts (:func:`vision.measure._background_slope`):
a lighting gradient across the cuts, smooth along the beam, recovered from the cuts' ends
although a sixth of them lie on something bright (the hub, the plate, clutter)."""

from __future__ import annotations

import math

import numpy as np

from vision.measure import _background_slope


def test_the_lights_gradient_across_the_cuts_is_recovered_past_ends_on_other_things() -> None:
    rng = np.random.default_rng(5)
    n_cuts, m_edge, noise_dn = 400, 8, 3.0
    a = np.linspace(0.03, 0.82, n_cuts)  # m along the beam
    t = np.arange(-0.04, 0.04 + 1e-12, 0.0005)  # m across, samples every half pixel
    true_slope = 12.0 + 6.0 * (a - 0.4) - 9.0 * (a - 0.4) ** 2  # DN per m, smooth
    prof = 55.0 + true_slope[:, None] * t[None, :] + rng.normal(0.0, noise_dn, (n_cuts, len(t)))
    prof[:, 40:-40] += 150.0  # the beam's light in the middle: not seen by the ends
    bad = rng.random(n_cuts) < 1 / 6
    prof[bad, -m_edge:] += 115.0  # one end on the hub
    got = _background_slope(prof, t, m_edge, a)
    # Each cut's slope: two medians of m_edge samples (sd ~1.25 noise / sqrt(m_edge)),
    # over the ends' span. A quadratic fitted to N cuts evenly along the beam: its value's
    # variance is at most 9/N of a cut's (at the ends of the range).
    span = float(t[-m_edge:].mean() - t[:m_edge].mean())
    sd_cut = math.sqrt(2.0) * 1.2533 * noise_dn / math.sqrt(m_edge) / span
    sd_fit = sd_cut * 3.0 / math.sqrt((~bad).sum())
    err = np.abs(got - true_slope)
    assert err.max() < 4.0 * sd_fit, (sd_fit, err.max())
