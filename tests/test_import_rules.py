"""The architecture's import rule: sim, vision and daq are independent siblings;
pipelines sits on top; nothing imports pipelines."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PACKAGES = ("sim", "vision", "daq", "pipelines")
FORBIDDEN = {
    "sim": {"vision", "daq", "pipelines"},
    "vision": {"sim", "daq", "pipelines"},
    "daq": {"sim", "vision", "pipelines"},
    "pipelines": set(),
}


def _imported_top_levels(path: Path) -> set[str]:
    tree = ast.parse(path.read_text("utf-8"), filename=str(path))
    names: set[str] = set()
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            names.update(alias.name.split(".")[0] for alias in node.names)
        elif isinstance(node, ast.ImportFrom) and node.level == 0 and node.module:
            names.add(node.module.split(".")[0])
    return names


@pytest.mark.parametrize("package", PACKAGES)
def test_package_imports_respect_the_layering(package: str) -> None:
    offenders = []
    for path in sorted((ROOT / package).rglob("*.py")):
        bad = _imported_top_levels(path) & FORBIDDEN[package]
        if bad:
            offenders.append(f"{path.relative_to(ROOT)} imports {sorted(bad)}")
    assert not offenders, "\n".join(offenders)


def test_nothing_outside_pipelines_tests_and_benchmarks_imports_pipelines() -> None:
    for package in ("sim", "vision", "daq"):
        for path in (ROOT / package).rglob("*.py"):
            assert "pipelines" not in _imported_top_levels(path), path


def test_heavy_libraries_stay_at_the_edge() -> None:
    """mcap only in daq's log modules, rerun only in pipelines.review's viewer modules."""
    for path in ROOT.joinpath("sim").rglob("*.py"):
        assert not _imported_top_levels(path) & {"cv2", "mcap", "rerun", "h5py", "xarray"}, path
    for package in PACKAGES:
        for path in (ROOT / package).rglob("*.py"):
            mods = _imported_top_levels(path)
            if "rerun" in mods:
                assert path.parent.name == "review" and path.stem in {"viewer", "layout", "rrd"}, (
                    path
                )
            if "nidaqmx" in mods:
                raise AssertionError(f"{path}: nidaqmx must be imported lazily inside a function")
