"""Smoke run of ``beambench bench sim --quick``: finite errors, a self-consistent reference."""

from __future__ import annotations

import math

import pytest

from pipelines.bench.sim import table


@pytest.mark.slow
def test_quick_table_is_finite_and_the_reference_is_self_consistent() -> None:
    rows, ref_err = table(quick=True)
    scenes = {r.scene for r in rows}
    assert "reciprocating" in scenes and any(s.startswith("spin-up") for s in scenes)
    for r in rows:
        assert math.isfinite(r.rel_error) and math.isfinite(r.wall_per_sim_s), r
        assert r.wall_per_sim_s >= 0.0
    for name, e in ref_err.items():
        # the reference moves far less than the errors it is used to measure
        worst_candidate = max(r.rel_error for r in rows if r.scene == name)
        assert e < 0.1 * worst_candidate, (name, e, worst_candidate)
    # the models converge towards the reference: every candidate within 1 %
    assert all(r.rel_error < 1e-2 for r in rows)
