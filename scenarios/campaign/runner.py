"""Running a campaign's cases: in this process, or on Dask distributed (a LocalCluster sized to the
machine, or an existing cluster by its scheduler address).

An existing scheduler is connected to before anything else (the output directory, the results
file): one that does not answer is `SchedulerUnreachable`, with nothing created.

The shell around `run_case`: draws the cases a batch at a time as the runs need them (so a
campaign of any allowed size starts within seconds and its memory does not grow with its size),
writes each case file, keeps a bounded number of runs in flight on the workers, and stores each
result row as it arrives (so an interrupted campaign resumes). No silent retries: tasks are
submitted with `retries=0`, and the local scheduler runs with
`distributed.scheduler.allowed-failures: 0`, so a run whose worker died (killed, out of memory)
comes back as an `error` row with the reason, instead of quietly running again elsewhere. Runs
are submitted grouped by scenario, floor, tape and floor seed within each batch, so a worker
that reuses its painted floor (`paint_ground_cached`) gets to.

Never reads a clock.
"""

from __future__ import annotations

import itertools
import logging
import os
import signal
import threading
from collections import Counter
from collections.abc import Callable, Iterable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from lanewarden.perception import line_kernel
from lanewarden.scenarios.campaign.cases import (
    CampaignSpec,
    Case,
    case_id,
    case_yaml,
    draw_case,
    spec_fingerprint,
)
from lanewarden.scenarios.campaign.run_case import case_columns, run_case
from lanewarden.scenarios.campaign.store import Recovery, ResultStore
from lanewarden.scenarios.errors import ScenarioError, ScenarioOutputError
from lanewarden.wording import counted

if TYPE_CHECKING:
    from distributed import Client

    from lanewarden.assembly import BuildStack

#: `--scheduler` value that runs every case in this process, one after the other (no Dask).
IN_PROCESS = "in-process"
#: `--scheduler` value (the default) that starts a LocalCluster sized to this machine.
LOCAL = "local"
SCHEDULER_ENV = "DASK_SCHEDULER_ADDRESS"
#: The most runs one campaign may have (`--runs`): 100,000 runs are days of CPU even on a
#: cluster; more is another seed in another directory.
MAX_RUNS = 100_000
#: Cases drawn (and case files written) at a time, after a first small batch.
DRAW_BATCH = 256
#: Runs submitted to the cluster per worker thread at a time.
IN_FLIGHT_PER_WORKER = 2
#: How long a campaign tries to reach an existing scheduler (`--scheduler ADDRESS`) before it
#: starts, s: Dask's own connect timeout (`Client(timeout=...)`, which retries a refused
#: connection until then). A scheduler that is up answers in milliseconds; Dask's default (30 s,
#: and 20 s here before) kept a campaign aimed at nothing waiting.
SCHEDULER_CONNECT_TIMEOUT_S = 5.0


class SchedulerUnreachable(ScenarioOutputError):
    """No Dask scheduler answers at `address` (a runtime failure, exit 1, as a camera or a base
    that cannot be reached): `problem` is Dask's reason."""

    def __init__(self, address: str, problem: str, named: str = "--scheduler") -> None:
        self.address, self.problem = address, problem
        super().__init__(f"{named} {address}: cannot connect ({problem}); expected a running "
                         f"Dask scheduler there, or --scheduler {LOCAL}")

    def named(self, named: str) -> SchedulerUnreachable:
        """The same failure, the address named as `named` says (e.g. the variable it came
        from)."""
        return SchedulerUnreachable(self.address, self.problem, named)


class FewerRunsThanStored(ScenarioError):
    """--runs below what the output directory already holds (a bad flag: exit 2; nothing is
    changed): `stored` runs, the highest of index `covers` - 1."""

    def __init__(self, path: Path, runs: int, stored: int, covers: int,
                 named: str | None = None) -> None:
        self.path, self.runs, self.stored, self.covers = path, runs, stored, covers
        super().__init__(
            f"{named or f'--runs {runs}'}: {path} already holds {counted(stored, 'run')} of "
            f"this campaign, up to {case_id(covers - 1)}; expected --runs {covers} or more (the "
            "report covers every stored run), or another --out for a smaller campaign")

    def named(self, named: str) -> FewerRunsThanStored:
        """The same refusal, naming the flag as `named` says (e.g. a default value)."""
        return FewerRunsThanStored(self.path, self.runs, self.stored, self.covers, named)


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
    #: Run only these runs (ids, all below `runs`): a screen (`--only-notable`); None: all.
    only: frozenset[str] | None = None


@dataclass
class CampaignProgress:
    total: int
    done: int
    counts: Counter[str] = field(default_factory=Counter)
    #: what `recover` carried over from a damaged results.sqlite (None: nothing to recover)
    recovered: Recovery | None = None
    #: rows an earlier campaign could not store, stored now
    unstored_carried: int = 0


def machine_workers() -> int:
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # not Linux
        return max(1, os.cpu_count() or 1)


def draw_cases(plan: CampaignPlan) -> list[Case]:
    """Every case of `plan` (a small plan's: the campaign itself draws them as it goes)."""
    return [_draw(plan, i) for i in range(plan.runs)]


def _draw(plan: CampaignPlan, index: int) -> Case:
    return draw_case(plan.spec, plan.spec_path, plan.seed, index, plan.config_overrides,
                     plan.follow_speed_m_s)


def write_case_files(out_dir: Path, cases: Iterable[Case]) -> None:
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


def pending_cases(plan: CampaignPlan, done: set[str], first_batch: int = 4,
                  batch: int = DRAW_BATCH) -> Iterator[Case]:
    """The cases not stored yet, drawn (and their case files written) a batch at a time as the
    runs need them, so the first runs start within seconds and memory does not grow with
    `plan.runs`; within a batch, grouped by scenario, floor, tape and floor seed (workers reuse
    floors)."""
    index = 0
    size = first_batch
    while index < plan.runs:
        indices = [i for i in range(index, min(plan.runs, index + size))
                   if case_id(i) not in done and (plan.only is None or case_id(i) in plan.only)]
        index += size
        size = batch
        cases = [_draw(plan, i) for i in indices]
        write_case_files(plan.out_dir, cases)
        yield from sorted(cases, key=lambda c: (str(c.scenario.get("name")), c.floor, c.tape,
                                                c.seed, c.camera, c.index))


def error_row(case: Case, reason: str) -> dict[str, Any]:
    """The row of a run that never came back (lost worker, cancelled, ...)."""
    return {**case_columns(case), "outcome": "error",
            "reason": " ".join(reason.split())[:500], "frames": 0, "metrics_json": "{}",
            "effects_json": "[]"}


def run_campaign(plan: CampaignPlan, scheduler: str = LOCAL, workers: int | None = None,
                 on_start: Callable[[CampaignProgress, str], None] | None = None,
                 on_row: Callable[[dict[str, Any], CampaignProgress], None] | None = None,
                 *, recover: bool = False,
                 connect_timeout_s: float | None = None) -> CampaignProgress:
    """Run every case of `plan` that has no stored result yet (or an error), storing each row.

    `scheduler`: LOCAL, IN_PROCESS or a Dask scheduler address; `recover`: carry a damaged
    results.sqlite's readable rows over (store.py). A scheduler address is connected to first
    (within `connect_timeout_s`, default SCHEDULER_CONNECT_TIMEOUT_S): SchedulerUnreachable
    before anything is created in `plan.out_dir`. `on_start` is called before the first case
    is drawn. A directory holding runs beyond `plan.runs` is refused (FewerRunsThanStored)
    before anything is drawn, run or reported. KeyboardInterrupt propagates after the cluster is
    shut down; every finished row is already stored."""
    timeout_s = SCHEDULER_CONNECT_TIMEOUT_S if connect_timeout_s is None else connect_timeout_s
    with _connected(scheduler, timeout_s) as client:
        return _run_stored(plan, scheduler, workers, client, on_start, on_row, recover)


def _run_stored(plan: CampaignPlan, scheduler: str, workers: int | None, client: Client | None,
                on_start: Callable[[CampaignProgress, str], None] | None,
                on_row: Callable[[dict[str, Any], CampaignProgress], None] | None,
                recover: bool) -> CampaignProgress:
    try:
        plan.out_dir.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ScenarioOutputError(f"--out {plan.out_dir}: cannot create the directory "
                                  f"({exc})") from exc
    with ResultStore(plan.out_dir / "results.sqlite", recover=recover) as store:
        store.claim({"spec": spec_fingerprint(plan.spec, plan.config_overrides),
                     "seed": str(plan.seed)})
        store.check()  # a row no campaign writes is refused before it is counted or rerun
        _refuse_fewer_runs(store, plan.runs)
        done = store.done_ids(below_index=plan.runs)
        total = plan.runs
        if plan.only is not None:
            total, done = len(plan.only), done & plan.only
        progress = CampaignProgress(total=total, done=len(done),
                                    counts=store.outcome_counts(plan.runs),
                                    recovered=store.recovered,
                                    unstored_carried=store.unstored_carried)
        if on_start is not None:
            on_start(progress, describe_scheduler(scheduler, workers))
        for row in _execute(pending_cases(plan, done), plan.build_stack, scheduler, client,
                            workers, plan.worker_memory_limit_mb):
            store.put(row)
            progress.done += 1
            progress.counts[str(row["outcome"])] += 1
            if on_row is not None:
                on_row(row, progress)
    return progress


def _refuse_fewer_runs(store: ResultStore, runs: int) -> None:
    """FewerRunsThanStored when `store` holds runs beyond the first `runs` (an earlier, larger
    --runs): the report would leave them out while results.sqlite keeps them."""
    stored, covers = store.extent()
    if covers > runs:
        raise FewerRunsThanStored(store.path, runs, stored, covers)


def describe_scheduler(scheduler: str, workers: int | None) -> str:
    if scheduler == IN_PROCESS:
        return "in this process"
    if scheduler == LOCAL:
        return f"local Dask cluster, {workers or machine_workers()} worker processes"
    return f"Dask scheduler {scheduler}"


@contextmanager
def _connected(scheduler: str, timeout_s: float) -> Iterator[Client | None]:
    """A client of the existing scheduler at address `scheduler`, closed afterwards (None for
    LOCAL and IN_PROCESS: a local cluster starts only when there is a run for it)."""
    if scheduler in (LOCAL, IN_PROCESS):
        yield None
        return
    from distributed import Client

    try:
        client = Client(scheduler, timeout=timeout_s)
    except OSError as exc:  # refused, timed out, no such host
        raise SchedulerUnreachable(scheduler, " ".join(str(exc).split())) from None
    try:
        yield client
    finally:
        client.close()


def _execute(cases: Iterator[Case], build_stack: BuildStack, scheduler: str,
             client: Client | None, workers: int | None,
             memory_limit_mb: int) -> Iterator[dict[str, Any]]:
    if scheduler == IN_PROCESS:
        for case in cases:
            yield run_case(case.model_dump_json(), build_stack)
        return
    first = next(cases, None)
    if first is None:
        return  # nothing to run: no cluster to start
    yield from _execute_on_dask(itertools.chain([first], cases), build_stack, client, workers,
                                memory_limit_mb)


@contextmanager
def _interrupts_ignored() -> Iterator[None]:
    """SIGINT ignored in this process for the block (main thread only; elsewhere a no-op)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    previous = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)


def _execute_on_dask(cases: Iterator[Case], build_stack: BuildStack, client: Client | None,
                     workers: int | None, memory_limit_mb: int) -> Iterator[dict[str, Any]]:
    """The runs on `client`'s cluster (an existing scheduler's, already connected), or, without
    one, on a LocalCluster started here and closed afterwards."""
    import dask
    from distributed import Client, LocalCluster, as_completed

    from lanewarden.scenarios.campaign.worker_plugin import LeaveInterruptsToTheParent

    line_kernel.ready()  # (before the workers: a compile happens, and is said, once)
    cluster = None
    with dask.config.set({"distributed.scheduler.allowed-failures": 0}):
        if client is None:
            # A terminal's Ctrl-C reaches the worker processes too (one process group): they
            # leave it to this process, which closes the cluster. Ignored while they start (a
            # process started with SIGINT ignored keeps ignoring it), and by the plugin in any
            # worker the nanny starts later (a restart after the memory limit).
            with _interrupts_ignored():
                cluster = LocalCluster(
                    n_workers=workers or machine_workers(), threads_per_worker=1, processes=True,
                    memory_limit=f"{memory_limit_mb}MB", host="127.0.0.1",
                    dashboard_address=None,
                    # no dashboard; its health/metrics HTTP server on any free local port
                    scheduler_kwargs={"dashboard_address": "127.0.0.1:0"},
                    # every run's failure is its own row; Dask's ERROR lines (a worker's
                    # heartbeat failing as the cluster closes after Ctrl-C, with a traceback)
                    # are noise on the user's terminal
                    silence_logs=logging.CRITICAL)
            client = Client(cluster)
            client.register_plugin(LeaveInterruptsToTheParent(), name="lanewarden-sigint")
    try:
        # Runs in flight at once: enough to keep every worker busy, few enough that the queue
        # (and the scheduler's memory) does not grow with the campaign.
        threads = sum(client.nthreads().values()) or (workers or machine_workers())
        in_flight = max(IN_FLIGHT_PER_WORKER * threads, 4)
        by_key: dict[object, Case] = {}
        running = as_completed()

        def submit(case: Case) -> None:
            future = client.submit(run_case, case.model_dump_json(), build_stack, pure=False,
                                   retries=0,
                                   key=f"lanewarden-case-{case.id}-{os.getpid()}-{id(case)}")
            by_key[future.key] = case
            running.add(future)

        for case in itertools.islice(cases, in_flight):
            submit(case)
        for future in running:
            case = by_key.pop(future.key)
            try:
                row = future.result()
            except Exception as exc:  # the run never came back: its row says why
                row = error_row(case, f"{type(exc).__name__}: {exc}")
            future.release()
            following = next(cases, None)
            if following is not None:
                submit(following)
            yield row
    finally:
        if cluster is not None:  # an existing scheduler's client is closed by `_connected`
            client.close()
            cluster.close()
