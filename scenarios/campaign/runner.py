"""Running a campaign's cases: in this process, or on Dask distributed (a LocalCluster sized to the
machine, or an existing cluster by its scheduler address).

The shell around `run_case`: draws the cases, writes each case file, sends the runs that are not
stored yet to the workers, and stores each result row as it arrives (so an interrupted campaign
resumes). No silent retries: tasks are submitted with `retries=0`, and the local scheduler runs
with `distributed.scheduler.allowed-failures: 0`, so a run whose worker died (killed, out of
memory) comes back as an `error` row with the reason, instead of quietly running again
elsewhere. Runs are submitted grouped by scenario, floor, tape and floor seed, so a worker that
reuses its painted floor (`paint_ground_cached`) gets to.

Wall time is read here for the progress bar and the report only.
"""

from __future__ import annotations

import logging
import os
from collections import Counter
from collections.abc import Callable, Iterator, Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from lanewarden.scenarios.campaign.cases import (
    CampaignSpec,
    Case,
    case_yaml,
    draw_case,
    spec_fingerprint,
)
from lanewarden.scenarios.campaign.run_case import case_columns, run_case
from lanewarden.scenarios.campaign.store import ResultStore
from lanewarden.scenarios.errors import ScenarioError

if TYPE_CHECKING:
    from lanewarden.assembly import BuildStack

#: `--scheduler` value that runs every case in this process, one after the other (no Dask).
IN_PROCESS = "in-process"
#: `--scheduler` value (the default) that starts a LocalCluster sized to this machine.
LOCAL = "local"
SCHEDULER_ENV = "DASK_SCHEDULER_ADDRESS"


@dataclass(frozen=True)
class CampaignPlan:
    """Everything a campaign needs; `config_overrides` is the --config file's content,
    `build_stack` the composition root's (`lanewarden.assembly.build_stack`, sent to workers)."""

    build_stack: BuildStack
    spec: CampaignSpec
    spec_path: Path
    seed: int
    runs: int
    out_dir: Path
    config_overrides: Mapping[str, Any]
    follow_speed_m_s: float
    worker_memory_limit_mb: int = 1024


@dataclass
class CampaignProgress:
    total: int
    done: int
    counts: Counter[str] = field(default_factory=Counter)


def machine_workers() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def draw_cases(plan: CampaignPlan) -> list[Case]:
    return [draw_case(plan.spec, plan.spec_path, plan.seed, i, plan.config_overrides,
                      plan.follow_speed_m_s) for i in range(plan.runs)]


def write_case_files(out_dir: Path, cases: list[Case]) -> None:
    folder = out_dir / "cases"
    try:
        folder.mkdir(parents=True, exist_ok=True)
        for case in cases:
            path = folder / f"{case.id}.yaml"
            text = case_yaml(case)
            if not path.exists() or path.read_text(encoding="utf-8") != text:
                path.write_text(text, encoding="utf-8")
    except OSError as exc:
        raise ScenarioError(f"{folder}: cannot write the case files ({exc})") from exc


def error_row(case: Case, reason: str) -> dict[str, Any]:
    """The row of a run that never came back (lost worker, cancelled, ...)."""
    return {**case_columns(case), "outcome": "error",
            "reason": " ".join(reason.split())[:500], "frames": 0, "metrics_json": "{}",
            "effects_json": "[]"}


def run_campaign(plan: CampaignPlan, scheduler: str = LOCAL, workers: int | None = None,
                 on_start: Callable[[CampaignProgress, str], None] | None = None,
                 on_row: Callable[[dict[str, Any], CampaignProgress], None] | None = None,
                 ) -> CampaignProgress:
    """Run every case of `plan` that has no stored result yet (or an error), storing each row.

    `scheduler`: LOCAL, IN_PROCESS or a Dask scheduler address. KeyboardInterrupt propagates
    after the cluster is shut down; every finished row is already stored."""
    try:
        plan.out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ScenarioError(f"--out {plan.out_dir}: cannot create the directory ({exc})") from exc
    cases = draw_cases(plan)
    write_case_files(plan.out_dir, cases)
    with ResultStore(plan.out_dir / "results.sqlite") as store:
        store.claim({"spec": spec_fingerprint(plan.spec, plan.config_overrides),
                     "seed": str(plan.seed)})
        done = store.done_ids()
        pending = sorted((c for c in cases if c.id not in done),
                         key=lambda c: (str(c.scenario.get("name")), c.floor, c.tape, c.seed,
                                        c.camera, c.index))
        progress = CampaignProgress(total=len(cases), done=len(cases) - len(pending))
        for row in store.rows(c.id for c in cases if c.id in done):
            progress.counts[str(row["outcome"])] += 1
        if on_start is not None:
            on_start(progress, describe_scheduler(scheduler, workers))
        for row in _execute(pending, plan.build_stack, scheduler, workers,
                            plan.worker_memory_limit_mb):
            store.put(row)
            progress.done += 1
            progress.counts[str(row["outcome"])] += 1
            if on_row is not None:
                on_row(row, progress)
    return progress


def describe_scheduler(scheduler: str, workers: int | None) -> str:
    if scheduler == IN_PROCESS:
        return "in this process"
    if scheduler == LOCAL:
        return f"local Dask cluster, {workers or machine_workers()} worker processes"
    return f"Dask scheduler {scheduler}"


def _execute(cases: list[Case], build_stack: BuildStack, scheduler: str, workers: int | None,
             memory_limit_mb: int) -> Iterator[dict[str, Any]]:
    if not cases:
        return
    if scheduler == IN_PROCESS:
        for case in cases:
            yield run_case(case.model_dump_json(), build_stack)
        return
    yield from _execute_on_dask(cases, build_stack, scheduler, workers, memory_limit_mb)


def _execute_on_dask(cases: list[Case], build_stack: BuildStack, scheduler: str,
                     workers: int | None, memory_limit_mb: int) -> Iterator[dict[str, Any]]:
    import dask
    from distributed import Client, LocalCluster, as_completed

    cluster = None
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        if scheduler == LOCAL:
            cluster = LocalCluster(
                n_workers=workers or machine_workers(), threads_per_worker=1, processes=True,
                memory_limit=f"{memory_limit_mb}MB", host="127.0.0.1", dashboard_address=None,
                # no dashboard; its health/metrics HTTP server on any free local port
                scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                silence_logs=logging.ERROR)
            client = Client(cluster)
        else:
            try:
                client = Client(scheduler, timeout="20s")
            except OSError as exc:
                raise ScenarioError(f"--scheduler {scheduler}: cannot connect ({exc})") from None
    try:
        by_key = {}
        futures = []
        for case in cases:
            future = client.submit(run_case, case.model_dump_json(), build_stack, pure=False,
                                   retries=0,
                                   key=f"lanewarden-case-{case.id}-{os.getpid()}-{id(case)}")
            by_key[future.key] = case
            futures.append(future)
        for future in as_completed(futures):
            case = by_key[future.key]
            try:
                row = future.result()
            except Exception as exc:  # the run never came back: its row says why
                row = error_row(case, f"{type(exc).__name__}: {exc}")
            future.release()
            yield row
    finally:
        client.close()
        if cluster is not None:
            cluster.close()
