"""``beambench reproduce``: the report's key numbers against closed forms, not against
itself; the whole report once (slow); bad ``--out`` and a failing run."""

from __future__ import annotations

import csv
import math
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from pipelines.cli import main
from pipelines.reproduce.damping import PRINTED_BETA_L, section_modes
from pipelines.reproduce.linkage import section_four_bar
from pipelines.reproduce.report import NUMBERS_NAME, REPORT_NAME, run_reproduce, write_report
from pipelines.reproduce.section import Section
from pipelines.reproduce.statics import TABLE2_GRAVITY_M_S2, section_table2
from pipelines.rig import Rig, load_rig
from sim.damping import log_decrement, log_decrement_from_damping_ratio


@pytest.fixture(scope="module")
def rig() -> Rig:
    return load_rig()


# -- four-bar -------------------------------------------------------------------------------
def _rocker_by_newton(rig: Rig, psi: float, phi: float) -> float:
    """Solve Eq. 4 for the rocker angle near ``phi`` (independent of sim.four_bar)."""
    a1, a2, a3, a4 = (rig.linkage.ground_m, rig.linkage.crank_m, rig.linkage.coupler_m,
                      rig.linkage.rocker_m)  # fmt: skip
    for _ in range(50):
        dx = a2 * math.cos(psi) - a1 - a4 * math.cos(phi)
        dy = a2 * math.sin(psi) - a4 * math.sin(phi)
        f = dx * dx + dy * dy - a3 * a3
        df = 2 * dx * a4 * math.sin(phi) - 2 * dy * a4 * math.cos(phi)
        phi -= f / df
    return phi


def test_four_bar_extrema_close_the_loop_and_are_stationary(rig: Rig) -> None:
    sec = section_four_bar(rig)
    a1, a2, a3, a4 = (rig.linkage.ground_m, rig.linkage.crank_m, rig.linkage.coupler_m,
                      rig.linkage.rocker_m)  # fmt: skip
    dead_centre = {"min": a3 + a2, "max": a3 - a2}  # crank and coupler extended / folded
    for end in ("min", "max"):
        psi = math.radians(sec.value(f"crank_at_{end}_deg"))
        phi = math.radians(sec.value(f"rocker_{end}_deg"))
        p = np.array([a2 * math.cos(psi), a2 * math.sin(psi)])
        q = np.array([a1 + a4 * math.cos(phi), a4 * math.sin(phi)])
        assert abs(np.linalg.norm(p - q) - a3) < 1e-12  # the four links close
        assert abs(np.linalg.norm(q) - dead_centre[end]) < 1e-12
        h = 1e-4
        slope = (_rocker_by_newton(rig, psi + h, phi) - _rocker_by_newton(rig, psi - h, phi)) / (
            2 * h
        )
        assert abs(slope) < 1e-7  # stationary (typical |d phi / d psi| ~ 0.7)
    # the paper's printed values are the rocker at crank 0 and pi, and not extrema
    assert sec.value("rocker_at_crank_0_deg") == pytest.approx(62.598, abs=5e-4)
    assert sec.value("rocker_at_crank_180_deg") == pytest.approx(150.474, abs=5e-4)
    assert sec.value("range_deg") == pytest.approx(88.917, abs=5e-4)
    assert sec.value("eq8_offset_deg") == pytest.approx(180.0, abs=1e-9)


# -- natural frequencies and damping --------------------------------------------------------
def test_clamped_free_eigenvalues_and_frequencies(rig: Rig) -> None:
    sec = section_modes(rig)
    b = rig.beam
    ei = b.youngs_modulus_pa * b.width_m * b.thickness_m**3 / 12.0
    rho_a = b.density_kg_m3 * b.width_m * b.thickness_m
    for n, printed in enumerate(PRINTED_BETA_L, start=1):
        beta = sec.value(f"beta_l_{n}")
        assert abs(math.cos(beta) + 1.0 / math.cosh(beta)) < 1e-12  # cos cosh + 1 = 0
        assert beta == pytest.approx(printed, abs=6e-5)
        assert beta == pytest.approx((n - 0.5) * math.pi, abs=0.31 if n == 1 else 0.02)
        f = (beta / b.length_m) ** 2 * math.sqrt(ei / rho_a) / (2 * math.pi)
        assert sec.value(f"frequency_hz_{n}") == pytest.approx(f, rel=2e-4)  # I to 1e-4


def test_eq37_damping_ratios_and_the_eq39_round_trip(rig: Rig) -> None:
    sec = section_modes(rig)
    w = [2 * math.pi * sec.value(f"frequency_hz_{n}") for n in (1, 2)]
    for a in (0.1, 0.00087):
        for n in (1, 2):
            zeta = a / (2 * w[n - 1]) + a * w[n - 1] / 2
            assert sec.value(f"zeta_{n}_{a:g}") == pytest.approx(zeta, rel=1e-12)
        assert sec.value(f"eq39_a0_{a:g}") == pytest.approx(a, rel=1e-10)
        assert sec.value(f"eq39_a1_{a:g}") == pytest.approx(a, rel=1e-10)
    assert sec.value("zeta_1_0.1") > 1.0  # the reciprocating damping is overdamped


# -- Table 2 --------------------------------------------------------------------------------
def test_table2_beam_theory_and_the_paper_row_geometry(rig: Rig) -> None:
    sec = section_table2(rig)
    b = rig.beam
    ei = b.youngs_modulus_pa * b.width_m * b.thickness_m**3 / 12.0
    expected_mm = {0.051: 27.73, 0.1: 54.38, 0.149: 81.03}  # with g = 9.81
    for mass, mm in expected_mm.items():
        delta = mass * TABLE2_GRAVITY_M_S2 * b.length_m**3 / (3.0 * ei)  # Eq. 47
        assert sec.value(f"theory_tip_{mass}") == pytest.approx(1e3 * delta, rel=1e-4)
        assert sec.value(f"theory_tip_{mass}") == pytest.approx(mm, abs=0.01)
    # the paper's "theoretical" strains are a straight line crossing zero at 825 mm; PL^3/3EI
    # with that length and the line's load is the printed row
    length = sec.value("theory_row_length_m")
    assert length == pytest.approx(0.825, abs=1e-4)
    for mass, printed in ((0.051, 26.84), (0.1, 52.14), (0.149, 77.33)):
        p = sec.value(f"theory_row_mass_{mass}") * TABLE2_GRAVITY_M_S2
        assert 1e3 * p * length**3 / (3.0 * ei) == pytest.approx(printed, abs=0.015)
    rows = {(r["source"], r["mass_kg"]): r for r in sec.tables["table2"]}
    for mass, printed in ((0.051, 27.23), (0.1, 51.86), (0.149, 76.90)):
        est = rows[("strain estimate (§5.1.3), L = 0.825 m", mass)]["tip_mm"]
        assert est == pytest.approx(printed, abs=0.05)


# -- report writing -------------------------------------------------------------------------
def _tiny_section(fail: bool = False) -> Section:
    sec = Section("tiny", "A tiny section")
    sec.add("one", "one", "1", 1.0, 1.0)
    sec.tables["tiny"] = [{"x_m": 1.0, "y_m": math.nan}]

    def draw(path: Path) -> None:
        if fail:
            raise RuntimeError("plot failed")
        path.write_bytes(b"png")

    sec.plots["tiny.png"] = draw
    return sec


def test_a_failing_run_leaves_the_old_report_and_no_temporary_folder(tmp_path: Path) -> None:
    out = tmp_path / "out"
    out.mkdir()
    (out / REPORT_NAME).write_text("old report")
    (out / "notes.txt").write_text("the user's")
    with pytest.raises(RuntimeError, match="plot failed"):
        write_report([_tiny_section(fail=True)], out, started_s=0.0)
    assert (out / REPORT_NAME).read_text() == "old report"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]
    write_report([_tiny_section()], out, started_s=0.0)
    assert "A tiny section" in (out / REPORT_NAME).read_text()
    assert (out / "notes.txt").read_text() == "the user's"  # other files left alone
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out"]


@pytest.mark.parametrize("kind", ["missing parent", "a file"])
def test_bad_out_is_one_error_line_and_exit_2(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], kind: str
) -> None:
    if kind == "a file":
        out = tmp_path / "report"
        out.write_text("not a folder")
    else:
        out = tmp_path / "missing" / "dir"
    assert main(["reproduce", "--out", str(out)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: --out ")
    assert not (tmp_path / "missing").exists()


# -- the whole report -----------------------------------------------------------------------
@pytest.fixture(scope="module")
def report(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Path]:
    out = tmp_path_factory.mktemp("reproduce") / "report"
    yield run_reproduce(out).parent


def _numbers(out: Path) -> dict[str, float]:
    with (out / NUMBERS_NAME).open(newline="", encoding="utf-8") as fh:
        return {r["key"]: float(r["beambench"]) for r in csv.DictReader(fh)}


@pytest.mark.slow
def test_the_report_writes_its_files_and_the_csvs_parse(report: Path) -> None:
    text = (report / REPORT_NAME).read_text(encoding="utf-8")
    for name in [*text.split("](")[1:]]:
        target = name.split(")")[0]
        assert (report / target).is_file(), target  # every linked plot and table exists
    for csv_path in report.glob("*.csv"):
        with csv_path.open(newline="", encoding="utf-8") as fh:
            rows = list(csv.DictReader(fh))
        assert rows, csv_path.name
    pngs = list(report.glob("*.png"))
    assert len(pngs) >= 8 and all(p.read_bytes()[:4] == b"\x89PNG" for p in pngs)
    assert "took" in text


@pytest.mark.slow
def test_free_decay_recovers_the_damping_within_the_method_tolerance(report: Path) -> None:
    n = _numbers(report)
    a_true = 0.00087
    # the log-decrement method's own error on a noise-free single mode like the decay
    w1 = 2 * math.pi * n["frequency_hz_1"]
    zeta = a_true / (2 * w1) + a_true * w1 / 2
    t = np.arange(4001) / 400.0
    y = np.exp(-zeta * w1 * t) * np.cos(w1 * math.sqrt(1 - zeta**2) * t)
    tol = abs(log_decrement(t, y) / log_decrement_from_damping_ratio(zeta) - 1)
    assert 1e-5 < tol < 1e-2
    assert abs(n["a_matched"] / a_true - 1) < tol
    assert abs(n["a_eq37"] / a_true - 1) < 1e-2  # one mode read alone: looser


@pytest.mark.slow
def test_spin_up_stiffening_and_the_four_bar_drive(report: Path) -> None:
    n = _numbers(report)
    for omega in ("4", "10"):
        assert n[f"stiffened_max_m_{omega}"] < n[f"unstiffened_max_m_{omega}"]
        assert n[f"stiffened_max_m_{omega}"] == pytest.approx(n[f"fe_max_m_{omega}"], rel=5e-3)
    assert n["tip_amplitude_mm_paper"] == pytest.approx(30.75, abs=0.2)
    assert n["fourbar_over_sinusoid"] > 1.1  # the true four-bar loads the beam harder
    assert n["cycle_change_m"] < 1e-9
