"""A campaign on a real lab cluster: a ``dask scheduler`` and two ``dask worker``
processes on 127.0.0.1 (random ports), three short synthetic runs recorded with
``beambench capture`` at crank frequencies other than the rig's, against the same runs
processed one at a time with ``beambench process``."""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import time
from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest

from pipelines.campaign import cluster as cluster_module
from pipelines.campaign.catalogue import read_catalogue, rows_of
from pipelines.campaign.summary import summarise_run
from pipelines.cli import main
from pipelines.results.io import read_results
from pipelines.review.rrd import rrd_entities
from pipelines.rig import default_rig_text

pytestmark = pytest.mark.slow

ROOT = Path(__file__).resolve().parents[3]
BIN = Path(sys.executable).parent
CRANK_HZ = {"run-a": 1.45, "run-b": 1.9, "run-c": 2.35}
DURATION_S = 3.0


def _env() -> dict[str, str]:
    env = dict(os.environ)
    env["PYTHONPATH"] = str(ROOT) + os.pathsep + env.get("PYTHONPATH", "")
    return env


def _rig_text(crank_hz: float) -> str:
    lines = []
    for line in default_rig_text().splitlines():
        if line.startswith("crank_frequency_hz"):
            line = f"crank_frequency_hz = {crank_hz}"
        elif line.startswith("warmup_s"):
            line = "warmup_s = 2.0"
        lines.append(line)
    return "\n".join(lines) + "\n"


@pytest.fixture(scope="module")
def log_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    d = tmp_path_factory.mktemp("campaign-logs")
    procs = []
    for name, hz in CRANK_HZ.items():
        rig = d.parent / f"{name}.toml"
        rig.write_text(_rig_text(hz))
        cmd = [str(BIN / "beambench"), "capture", "--duration", str(DURATION_S)]
        cmd += ["--rig", str(rig), "--out", str(d / f"{name}.mcap")]
        procs.append(subprocess.Popen(cmd, env=_env(), stdout=subprocess.DEVNULL))
    try:
        for p in procs:
            # a hang guard: three captures at once took 125 s on this shared 2-core
            # machine under a load average of 17
            assert p.wait(timeout=600) == 0
    finally:
        for p in procs:  # none left running to be collected (a ResourceWarning) later
            if p.poll() is None:
                p.kill()
                p.wait()
    return d


class Cluster:
    def __init__(self, tmp: Path) -> None:
        self.procs: dict[str, subprocess.Popen[bytes]] = {}
        sched_file = tmp / "scheduler.json"
        self.procs["scheduler"] = subprocess.Popen(
            [
                *(str(BIN / "dask"), "scheduler", "--host", "127.0.0.1", "--port", "0"),
                *("--no-dashboard", "--scheduler-file", str(sched_file)),
            ],
            env=_env(),
            stdout=subprocess.DEVNULL,
            stderr=subprocess.DEVNULL,
        )
        deadline = time.monotonic() + 30
        while not sched_file.exists() and time.monotonic() < deadline:
            time.sleep(0.1)
        self.address = json.loads(sched_file.read_text())["address"]
        for name in ("w0", "w1"):
            # no nanny: a killed worker stays dead (a nanny would restart it)
            self.procs[name] = subprocess.Popen(
                [
                    *(str(BIN / "dask"), "worker", self.address, "--name", name),
                    *("--nthreads", "1", "--no-nanny", "--no-dashboard", "--host", "127.0.0.1"),
                    *("--local-directory", str(tmp / name)),
                ],
                env=_env(),
                stdout=subprocess.DEVNULL,
                stderr=subprocess.DEVNULL,
            )
        self.wait_for_workers(2)

    def client(self):  # type: ignore[no-untyped-def]
        from distributed import Client

        return Client(self.address, timeout=10, set_as_default=False)

    def wait_for_workers(self, n: int) -> None:
        with self.client() as c:
            c.wait_for_workers(n, timeout=60)

    def close(self) -> None:
        # the workers first: a worker whose scheduler left before it was stopped may try
        # to reconnect instead of exiting (in one case of two here: 10 s, then killed)
        workers = [p for name, p in self.procs.items() if name != "scheduler"]
        for group in (workers, [self.procs["scheduler"]]):
            for p in group:
                if p.poll() is None:
                    p.send_signal(signal.SIGTERM)
            for p in group:
                try:
                    p.wait(timeout=10)
                except subprocess.TimeoutExpired:
                    p.kill()
                    p.wait()


@pytest.fixture(scope="module")
def cluster(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Cluster]:
    c = None
    try:
        c = Cluster(tmp_path_factory.mktemp("dask"))
        yield c
    finally:
        if c is not None:
            c.close()


@pytest.fixture(scope="module")
def one_at_a_time(log_dir: Path, tmp_path_factory: pytest.TempPathFactory) -> dict[str, Path]:
    out = tmp_path_factory.mktemp("single")
    paths = {}
    for name in CRANK_HZ:
        paths[name] = out / f"{name}.nc"
        rc = main(["process", str(log_dir / f"{name}.mcap"), "--out", str(paths[name])])
        assert rc == 0
    return paths


def _check_against_single(out: Path, single: dict[str, Path]) -> None:
    rows = rows_of(read_catalogue(out / "campaign.nc"))
    assert sorted(rows) == sorted(CRANK_HZ)
    for name, hz in CRANK_HZ.items():
        row = rows[name]
        assert row["status"] == "ok", row["error"]
        ref = read_results(single[name])
        mine = read_results(row["results_file"])
        for var in ("tip_lateral", "tip_lateral_strain", "sim_tip_lateral", "frame_time"):
            np.testing.assert_array_equal(mine[var].values, ref[var].values)
        for key, value in summarise_run(ref).items():
            assert row[key] == value or (np.isnan(row[key]) and np.isnan(value)), key
        # the crank frequency measured from the rocker is the rig's, to its uncertainty
        assert abs(row["crank_frequency_hz"] - hz) < 4 * row["crank_frequency_sd_hz"] + 1e-6
        assert row["run_id"] and row["start_time_utc"].endswith("Z")
        assert len(row["log_sha256"]) == 64 and len(row["rig_sha256"]) == 64


def test_campaign_on_a_lab_cluster_equals_runs_processed_one_at_a_time(
    cluster: Cluster,
    log_dir: Path,
    one_at_a_time: dict[str, Path],
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
) -> None:
    out = tmp_path / "campaign"
    assert main(["campaign", str(log_dir), "--out", str(out), "--scheduler", cluster.address]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert sum(": ok, crank " in line for line in lines) == 3
    assert (out / "campaign.md").read_text().count("\n| run-") == 3
    _check_against_single(out, one_at_a_time)
    # both workers took part
    rows = rows_of(read_catalogue(out / "campaign.nc"))
    assert len({r["worker"] for r in rows.values()}) == 2


def test_a_sweep_through_the_lab_cluster_overlays_the_runs(
    cluster: Cluster, one_at_a_time: dict[str, Path], tmp_path: Path
) -> None:
    out = tmp_path / "sweep.nc"
    args = ["sweep", "reciprocating", "--crank-hz", "1.45:2.35:5", "--out", str(out)]
    assert main([*args, "--scheduler", cluster.address]) == 0
    import xarray as xr

    with xr.open_dataset(out, engine="h5netcdf") as opened:
        ds = opened.load()
    assert ds["tip_lateral_amplitude_m"].dims == ("crank_hz", "a1")
    assert ds.sizes["crank_hz"] == 5 and ds.attrs["drive"] == "fourbar"
    for name, hz in CRANK_HZ.items():
        run = summarise_run(read_results(one_at_a_time[name]))
        point = ds.sel(crank_hz=hz, a1=ds["a1"].values[0])
        # the run's simulation is driven by the measured rocker, the sweep's by the exact
        # four-bar: two simulations at 2 % each (process's and sweep's --sim-tol)
        amp = float(point["tip_lateral_amplitude_m"])
        assert amp == pytest.approx(run["tip_lateral_sim_amplitude_m"], rel=0.04)
        # and a 2 % error of the complex amplitude turns its phase by at most 0.02 rad
        lag = float(point["tip_lateral_phase_lag_rad"])
        assert lag == pytest.approx(run["tip_lateral_sim_phase_lag_rad"], abs=0.04)


def test_a_failed_run_is_recorded_and_a_rerun_does_only_what_is_missing(
    cluster: Cluster, log_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    logs = tmp_path / "logs"
    logs.mkdir()
    for name in ("run-a", "run-b"):
        (logs / f"{name}.mcap").symlink_to(log_dir / f"{name}.mcap")
    whole = (log_dir / "run-c.mcap").read_bytes()
    (logs / "run-c.mcap").write_bytes(whole[: len(whole) // 3])  # a recording cut short
    out = tmp_path / "campaign"
    args = ["campaign", str(logs), "--out", str(out), "--scheduler", cluster.address]
    assert main(args) == 1
    captured = capsys.readouterr()
    assert "failed: run-c: " in captured.err and "Traceback" not in captured.err
    rows = rows_of(read_catalogue(out / "campaign.nc"))
    assert rows["run-c"]["status"] == "failed" and "run-c.mcap" in rows["run-c"]["error"]
    assert [rows[n]["status"] for n in ("run-a", "run-b")] == ["ok", "ok"]

    # the log recovered whole and a results file lost: only those two are done again
    (logs / "run-c.mcap").write_bytes(whole)
    Path(rows["run-a"]["results_file"]).unlink()
    assert main(args) == 0
    text = capsys.readouterr().out
    assert "1 of 3 runs already done" in text and "2 processed, 1 skipped, 0 failed" in text
    rows = rows_of(read_catalogue(out / "campaign.nc"))
    assert all(r["status"] == "ok" and Path(r["results_file"]).is_file() for r in rows.values())


def test_bad_input_is_one_error_line(
    log_dir: Path,
    tmp_path: Path,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    empty = tmp_path / "empty"
    empty.mkdir()
    assert main(["campaign", str(empty), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert err.startswith("error: ") and err.count("\n") == 1 and "no .mcap logs" in err
    junk = tmp_path / "junk.nc"
    junk.write_bytes(b"not a sweep")
    assert main(["campaign", str(log_dir), "--out", str(tmp_path / "o"), "--sweep", str(junk)]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"error: --sweep {junk}: ") and err.count("\n") == 1
    import socket

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    # Dask retries a refused connection until the timeout: 1 s here instead of 5
    monkeypatch.setattr(cluster_module, "CONNECT_TIMEOUT_S", 1.0)
    t0 = time.monotonic()
    rc = main(
        [
            "campaign",
            str(log_dir),
            "--out",
            str(tmp_path / "o"),
            "--scheduler",
            f"tcp://127.0.0.1:{port}",
        ]
    )
    assert rc == 2 and time.monotonic() - t0 < 30
    err = capsys.readouterr().err
    assert err.startswith("error: --scheduler tcp://127.0.0.1:") and err.count("\n") == 1


def test_killing_a_worker_mid_campaign_loses_nothing(
    cluster: Cluster, log_dir: Path, one_at_a_time: dict[str, Path], tmp_path: Path
) -> None:
    """Runs last: it leaves the cluster with one worker."""
    out = tmp_path / "campaign"
    cmd = [str(BIN / "beambench"), "campaign", str(log_dir), "--out", str(out)]
    proc = subprocess.Popen(
        [*cmd, "--scheduler", cluster.address],
        env=_env(),
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        with cluster.client() as c:
            victim = None
            deadline = time.monotonic() + 60
            while victim is None and time.monotonic() < deadline:
                info = c.scheduler_info(n_workers=-1)["workers"]
                for addr, keys in c.processing().items():
                    if keys and info.get(addr, {}).get("name") == "w0":
                        victim = addr
                time.sleep(0.05)
        assert victim is not None, "no run reached worker w0"
        cluster.procs["w0"].kill()
        stdout, stderr = proc.communicate(timeout=120)
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, stderr
    assert "3 processed, 0 skipped, 0 failed" in stdout
    _check_against_single(out, one_at_a_time)
    shutil.rmtree(out)


def test_a_scheduler_that_dies_mid_campaign_is_one_error_and_keeps_what_finished(
    log_dir: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The scheduler killed after the first run finished: one ``error:`` line and exit 2
    (not a wait for a scheduler that never answers), the finished runs' results and
    catalogue rows kept; a rerun on a fresh cluster does only the rest."""
    out = tmp_path / "campaign"
    for d in ("dask-1", "dask-2"):
        (tmp_path / d).mkdir()
    first = Cluster(tmp_path / "dask-1")
    try:
        cmd = [str(BIN / "beambench"), "campaign", str(log_dir), "--out", str(out)]
        proc = subprocess.Popen(
            [*cmd, "--scheduler", first.address],
            env=_env(),
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )
        try:
            assert proc.stdout is not None
            lines = []
            for line in proc.stdout:
                lines.append(line)
                if line.startswith("[1/3] "):
                    break
            first.procs["scheduler"].kill()
            rest, stderr = proc.communicate(timeout=180)  # a hang guard, not a speed assert
        finally:
            if proc.poll() is None:
                proc.kill()
                proc.wait()
    finally:
        first.close()
    lines += rest.splitlines()
    assert proc.returncode == 2, stderr
    assert stderr.startswith("error: ") and stderr.count("\n") == 1, stderr
    assert "lost the scheduler" in stderr and first.address in stderr
    finished = sorted(line.split()[1].rstrip(":") for line in lines if ": ok, crank " in line)
    assert 1 <= len(finished) < 3, lines
    rows = rows_of(read_catalogue(out / "campaign.nc"))
    assert sorted(rows) == finished
    assert all(r["status"] == "ok" and Path(r["results_file"]).is_file() for r in rows.values())

    second = Cluster(tmp_path / "dask-2")
    try:
        args = ["campaign", str(log_dir), "--out", str(out), "--scheduler", second.address]
        assert main([*args, "--rrd", str(out / "campaign.rrd")]) == 0
    finally:
        second.close()
    text = capsys.readouterr().out
    n = len(finished)
    assert f"{n} of 3 runs already done" in text
    assert f"{3 - n} processed, {n} skipped, 0 failed" in text
    rows = rows_of(read_catalogue(out / "campaign.nc"))
    assert sorted(rows) == sorted(CRANK_HZ)
    assert all(r["status"] == "ok" and Path(r["results_file"]).is_file() for r in rows.values())
    # the campaign's Rerun recording: every run at its measured crank frequency
    entities = rrd_entities(out / "campaign.rrd")
    for name in CRANK_HZ:
        for src in ("image", "strain", "sim"):
            assert entities[f"/runs/{name}/amplitude/{src}"].rows == 1
