"""Campaigns on Dask distributed: the same rows in this process, on a LocalCluster and on a
separately started scheduler with two workers on 127.0.0.1; a worker killed mid-campaign gives
error rows for its runs, and a rerun fills them in; a terminal's Ctrl-C stops a local-cluster
campaign with one line.

Heavy (starts Dask processes): about 20-40 s in all."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path

import pytest

from lanewarden.assembly import build_stack
from lanewarden.scenarios.campaign.cases import load_campaign_spec
from lanewarden.scenarios.campaign.run_case import DETERMINISTIC_COLUMNS
from lanewarden.scenarios.campaign.runner import IN_PROCESS, LOCAL, CampaignPlan, run_campaign
from lanewarden.scenarios.campaign.store import ResultStore
from tests.processes import interrupted

pytest.importorskip("distributed")

WAIT_S = 120.0


def plan(spec_path: Path, out: Path, runs: int) -> CampaignPlan:
    spec, path = load_campaign_spec(str(spec_path))
    return CampaignPlan(build_stack=build_stack, spec=spec, spec_path=path, seed=11, runs=runs,
                        out_dir=out, config_overrides={}, follow_speed_m_s=0.2,
                        worker_memory_limit_mb=1024)


def deterministic(out: Path) -> list[tuple[object, ...]]:
    with ResultStore(out / "results.sqlite") as store:
        return [tuple(r[c] for c in DETERMINISTIC_COLUMNS) for r in store.rows()]


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


@pytest.fixture
def external_cluster(tmp_path: Path) -> Iterator[tuple[str, list[subprocess.Popen[bytes]]]]:
    """`dask scheduler` and two `dask worker` processes (no nanny), stopped afterwards."""
    from distributed import Client

    port = free_port()
    address = f"tcp://127.0.0.1:{port}"
    env = {**os.environ, "DASK_DISTRIBUTED__SCHEDULER__ALLOWED_FAILURES": "0"}
    log = (tmp_path / "dask.log").open("wb")
    procs = [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler",
                               "--host", "127.0.0.1", "--port", str(port),
                               "--no-dashboard"], env=env, stdout=log, stderr=log)]
    try:
        for _ in range(2):
            procs.append(subprocess.Popen(
                [sys.executable, "-m", "distributed.cli.dask_worker", address, "--nthreads",
                 "1", "--no-nanny", "--no-dashboard", "--host", "127.0.0.1"],
                env=env, stdout=log, stderr=log))
        with Client(address, timeout="60s") as client:
            client.wait_for_workers(2, timeout=WAIT_S)
        yield address, procs[1:]
    finally:
        for proc in reversed(procs):
            if proc.poll() is None:
                proc.terminate()
        for proc in procs:
            try:
                proc.wait(timeout=30)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait()
        log.close()


def test_same_rows_in_process_on_a_local_cluster_and_on_a_separate_scheduler(
        tiny_spec: Path, tmp_path: Path,
        external_cluster: tuple[str, list[subprocess.Popen[bytes]]]) -> None:
    address, _ = external_cluster
    results = {}
    for name, scheduler, workers in (("inline", IN_PROCESS, None), ("local", LOCAL, 2),
                                     ("external", address, None)):
        out = tmp_path / name
        progress = run_campaign(plan(tiny_spec, out, 4), scheduler, workers)
        assert progress.done == 4
        results[name] = deterministic(out)
    assert len(results["inline"]) == 4
    assert results["local"] == results["inline"]
    assert results["external"] == results["inline"]


def test_a_killed_worker_gives_error_rows_and_a_rerun_fills_them_in(
        tiny_spec: Path, tmp_path: Path,
        external_cluster: tuple[str, list[subprocess.Popen[bytes]]]) -> None:
    from distributed import Client

    address, workers = external_cluster
    out = tmp_path / "killed"
    first_row = threading.Event()
    killed: list[int] = []

    def on_row(row: dict[str, object], progress: object) -> None:
        first_row.set()

    campaign = threading.Thread(
        target=run_campaign, args=(plan(tiny_spec, out, 8), address, None),
        kwargs={"on_row": on_row}, daemon=True)
    campaign.start()
    assert first_row.wait(WAIT_S)
    with Client(address, timeout="30s") as client:
        pids = client.run(os.getpid)
        deadline = time.monotonic() + WAIT_S
        while not killed and time.monotonic() < deadline:
            busy = [addr for addr, keys in client.processing().items() if keys]
            if busy:
                os.kill(pids[busy[0]], signal.SIGKILL)
                killed.append(pids[busy[0]])
    assert killed
    campaign.join(WAIT_S)
    assert not campaign.is_alive()
    with ResultStore(out / "results.sqlite") as store:
        rows = store.rows()
    lost = [r for r in rows if r["outcome"] == "error"]
    assert len(rows) == 8
    assert lost and all("KilledWorker" in str(r["reason"]) for r in lost)
    run_campaign(plan(tiny_spec, out, 8), IN_PROCESS)
    with ResultStore(out / "results.sqlite") as store:
        assert [r["outcome"] for r in store.rows() if r["outcome"] == "error"] == []


def test_ctrl_c_on_a_terminal_stops_a_local_cluster_campaign_with_one_line(
        tiny_spec: Path, tmp_path: Path) -> None:
    """A terminal's Ctrl-C reaches the whole process group, Dask's worker processes too: each
    printed a KeyboardInterrupt traceback (about 30 lines) after the campaign's own line. They
    leave it to the campaign now, which closes the cluster and keeps the finished runs."""
    out = tmp_path / "campaign"

    def stored() -> int:
        if not (out / "results.sqlite").exists():
            return 0
        with ResultStore(out / "results.sqlite") as store:
            return len(store.rows())

    # Interrupted once a run is stored: both workers started, one between runs or in the next.
    code, err = interrupted(["campaign", "--spec", str(tiny_spec), "--out", str(out),
                             "--runs", "8", "--workers", "2", "--quiet"],
                            lambda: stored() >= 1, whole_group=True)
    assert code == 130
    assert err.splitlines() == [  # (no blank line: a new user found one)
        "campaign tiny: 8 runs (seed 0), 0 already stored; running local Dask cluster, 2 worker "
        "processes",
        f"lanewarden: error: interrupted: {stored()} of 8 runs are stored in "
        f"{out / 'results.sqlite'} (report.html and junit.xml cover them); run the same command "
        "again to resume"]
    assert 1 <= stored() < 8
