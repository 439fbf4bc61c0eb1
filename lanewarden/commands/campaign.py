"""`lanewarden campaign`: a fault-injection campaign on Dask distributed (or in this process).

Thin shell: parse flags, load the config and the campaign spec, run the cases through
`scenarios.campaign.runner` with progress on stderr (outcome counts; a bar on a terminal, a line
every few seconds otherwise), then write junit.xml and report.html from the stored rows (read one
at a time). Ctrl-C leaves a resumable result file (exit 130); a damaged one is refused in one
line until `--recover` (scenarios/campaign/store.py).
"""

from __future__ import annotations

import os
import signal
import time
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

import click

from lanewarden.assembly import build_stack
from lanewarden.commands.config_cmd import config_option
from lanewarden.commands.flags import PathFlag, WholeRange
from lanewarden.commands.output_folders import (
    refuse_a_recording_folder,
    refuse_another_commands_folder,
)
from lanewarden.config import load_config
from lanewarden.errors import Interrupted, UsageError
from lanewarden.scenarios.campaign.cases import MAX_SEED, draw_case, load_campaign_spec
from lanewarden.scenarios.campaign.compare import NEAR_TAPE_M, drawn_difference, is_notable
from lanewarden.scenarios.campaign.outcome import OUTCOMES
from lanewarden.scenarios.campaign.report import (
    CampaignSummary,
    summarize,
    write_junit,
    write_report,
)
from lanewarden.scenarios.campaign.run_case import case_columns
from lanewarden.scenarios.campaign.runner import (
    IN_PROCESS,
    LOCAL,
    MAX_RUNS,
    SCHEDULER_ENV,
    CampaignPlan,
    CampaignProgress,
    FewerRunsThanStored,
    SchedulerUnreachable,
    machine_workers,
    run_campaign,
)
from lanewarden.scenarios.campaign.store import CampaignMismatch, ResultStore, results_in
from lanewarden.scenarios.errors import ScenarioError, ScenarioOutputError
from lanewarden.scenarios.progress import Progress
from lanewarden.stop_signals import raise_interrupt
from lanewarden.wording import counted

EXAMPLES = """\b
Examples:
  lanewarden campaign --spec default --out campaign-out --runs 200
  lanewarden campaign --spec my-spec.yaml --out big --runs 5000 --scheduler tcp://10.0.0.5:8786
  lanewarden sim --case campaign-out/cases/r00042.yaml
  lanewarden campaign --spec default --out screen --config mine.yaml --only-notable campaign-out
"""


def _counts(progress: CampaignProgress) -> str:
    return _outcome_counts(progress.counts)


def _outcome_counts(counts: Mapping[str, int]) -> str:
    """'safe_halt=3 nominal=2': the outcomes with runs, in OUTCOMES' order."""
    return " ".join(f"{o}={counts[o]}" for o in OUTCOMES if counts.get(o))


#: The most local worker processes per core: beyond it they only share the cores (64 workers on
#: a 2-core machine did not finish a 3 s run in 2 minutes, and took 1.5 GB more memory).
MAX_WORKERS_PER_CORE = 4


def _check_local_workers(workers: int, memory_limit_mb: int) -> None:
    """UsageError for more local worker processes than this machine can run: more than
    MAX_WORKERS_PER_CORE per core, or more than its memory holds at their memory limit."""
    cores = machine_workers()
    if workers > MAX_WORKERS_PER_CORE * cores:
        raise UsageError(f"--workers {workers}: this machine has {counted(cores, 'core')}; "
                         f"expected at most {MAX_WORKERS_PER_CORE * cores} local worker "
                         f"processes ({MAX_WORKERS_PER_CORE} per core: more only share them)")
    try:
        memory_mb = os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES") // 2**20
    except (AttributeError, ValueError, OSError):
        return  # (a system that does not say: the workers' own limits still hold)
    if workers * memory_limit_mb > memory_mb:
        raise UsageError(f"--workers {workers}: at campaign.worker_memory_limit_mb "
                         f"{memory_limit_mb} each they may use {workers * memory_limit_mb} MB, "
                         f"more than this machine's {memory_mb} MB; expected at most "
                         f"{counted(max(1, memory_mb // memory_limit_mb), 'worker')}, or a "
                         "lower limit")


@click.command("campaign", epilog=EXAMPLES)
@click.option("--spec", "spec_name", required=True, metavar="FILE|default",
              help="The campaign spec: a YAML file, or 'default' (every fault kind across the "
              "library scenarios and several cameras).")
@click.option("--out", "out_dir", required=True,
              type=PathFlag("a folder", file_okay=False),
              help="Output directory: results.sqlite, cases/, junit.xml, report.html. Running "
              "again with the same spec and seed resumes.")
@click.option("--runs", type=WholeRange(1, MAX_RUNS), default=None,
              help=f"Number of runs to draw (default: 100; at most {MAX_RUNS:,}: more is "
              "another --seed in another --out). Resuming, at least the runs --out holds.")
@click.option("--seed", type=WholeRange(0, MAX_SEED), default=0, show_default=True,
              help="Campaign seed: the same seed draws the same cases.")
@click.option("--scheduler", default=None, metavar="ADDRESS|local|in-process",
              help=f"A Dask scheduler address (default: ${SCHEDULER_ENV} if set, else a "
              "local cluster with one single-threaded worker process per core); 'in-process' "
              "runs without Dask.")
@click.option("--workers", type=WholeRange(1, 512), default=None,
              help="Worker processes of the local cluster (default: one per core; at most four "
              "per core, and as many as the machine's memory holds at "
              "campaign.worker_memory_limit_mb each).")
@config_option
@click.option("--quiet", is_flag=True, help="No progress (a bar on a terminal, else a line every "
              "few seconds).")
@click.option("--recover", is_flag=True,
              help="results.sqlite is damaged: keep it as results.sqlite.damaged, carry over "
              "every run that can still be read, and rerun the rest.")
@click.option("--only-notable", "notable_dir", default=None,
              type=PathFlag("a campaign's --out folder"), metavar="DIR",
              help="A screen: run only the runs that DIR (a campaign of the same spec and seed) "
              "found unsafe, false halts, on a false lane or within 30 mm of a tape; then "
              "`lanewarden compare DIR` this --out.")
def campaign_command(spec_name: str, out_dir: str, runs: int | None, seed: int,
                     scheduler: str | None, workers: int | None, config_path: str | None,
                     quiet: bool, recover: bool, notable_dir: str | None) -> None:
    """Draw randomized fault-injection runs from a spec, run them on Dask, classify each
    (safe_halt, recovered, nominal, false_halt, unsafe, error), write results and a report."""
    started = time.perf_counter()
    config = load_config(config_path)
    try:
        spec, spec_path = load_campaign_spec(spec_name)
    except ScenarioError as exc:
        raise UsageError(str(exc)) from None
    named = "--scheduler" if scheduler else f"${SCHEDULER_ENV}"
    scheduler = scheduler or os.environ.get(SCHEDULER_ENV) or LOCAL
    if scheduler not in (LOCAL, IN_PROCESS):
        _check_scheduler_address(scheduler, named)
    if scheduler == LOCAL and workers is not None:
        _check_local_workers(workers, config.campaign.worker_memory_limit_mb)
    overrides: dict[str, Any] = config.model_dump(mode="json", exclude_defaults=True)
    out = Path(out_dir)
    refuse_a_recording_folder(out)
    refuse_another_commands_folder(out, "campaign")
    notable: dict[str, dict[str, Any]] | None = None
    if notable_dir is not None:
        notable, runs = _notable(Path(notable_dir), out, runs, seed)
    only = None if notable is None else frozenset(notable)
    plan = CampaignPlan(build_stack=build_stack, spec=spec, spec_path=spec_path, seed=seed,
                        runs=runs or 100, out_dir=out, config_overrides=overrides,
                        follow_speed_m_s=config.supervisor.follow_speed_m_s,
                        worker_memory_limit_mb=config.campaign.worker_memory_limit_mb,
                        only=only)
    if notable is not None:
        _same_draws(plan, Path(str(notable_dir)), notable)
    bar: Progress | None = None
    stored_at_start = 0

    def on_start(progress: CampaignProgress, where: str) -> None:
        nonlocal bar, stored_at_start
        stored_at_start = progress.done
        recovered = progress.recovered
        if recovered is not None:
            click.echo(f"campaign {spec.name}: the damaged results database is kept as "
                       f"{recovered.kept_as}; {recovered.count} stored runs carried over"
                       + (f", {recovered.lost_ids} unreadable (they run again)"
                          if recovered.lost_ids else ""), err=True)
        if progress.unstored_carried:
            carried = progress.unstored_carried
            click.echo(f"campaign {spec.name}: stored now what an earlier campaign could not "
                       f"store ({counted(carried, 'run')})", err=True)
        if only is not None:
            click.echo(f"campaign {spec.name}: only the notable runs of {notable_dir} (unsafe, "
                       "false halts, on a false lane or within 30 mm of a tape)", err=True)
        click.echo(f"campaign {spec.name}: {counted(progress.total, 'run')} (seed {seed}), "
                   f"{progress.done} already stored; running {where}", err=True)
        bar = Progress(progress.total, f"campaign {spec.name}", "runs", initial=progress.done,
                       enabled=not quiet, heartbeat=True)
        bar.set_postfix(_counts(progress))

    def on_row(row: dict[str, Any], progress: CampaignProgress) -> None:
        if bar is not None:
            bar.set_postfix(_counts(progress))
            bar.advance_to(progress.done)

    # SIGTERM stops a campaign like Ctrl-C: the cluster is shut down, finished rows stay.
    previous = signal.signal(signal.SIGTERM, raise_interrupt)
    finished = False
    try:
        progress = run_campaign(plan, scheduler, workers, on_start, on_row, recover=recover)
        finished = True
    except CampaignMismatch as exc:
        raise UsageError(f"--out {out}: {exc}") from None
    except FewerRunsThanStored as exc:
        if runs is None:  # the default: said so, the user typed no --runs
            raise exc.named(f"--runs {plan.runs} (the default)") from None
        raise
    except SchedulerUnreachable as exc:  # named as the user gave it (flag or variable)
        raise exc.named(named) from None
    except KeyboardInterrupt:
        if bar is None:  # still connecting to the scheduler or opening results.sqlite
            raise Interrupted("before any run started") from None
        bar.close(finished=False)
        # the report and junit.xml of the runs stored so far (a safety reviewer's review: an
        # interrupted campaign had left neither, and its progress bar showed fewer runs than
        # were stored); one line (it had been this, a blank line and "lanewarden: error:
        # interrupted")
        stored, _ = _write_outputs(out, spec.name, plan.runs, lambda summary: (
            f"INTERRUPTED: {summary.runs} of {counted(plan.runs, 'run')} of spec {spec.name} "
            f"stored (seed {seed}); run the same command again to resume: "
            f"{_outcome_counts(summary.counts)}"))
        raise Interrupted(f"{stored} of {counted(plan.runs, 'run')} are stored in "
                          f"{out / 'results.sqlite'} (report.html and junit.xml cover them); "
                          "run the same command again to resume") from None
    finally:
        signal.signal(signal.SIGTERM, previous)
        if bar is not None:
            bar.close(finished=finished)
    screen = ("" if only is None else
              f"; a screen: only the notable runs of {notable_dir}, not a sample")

    def said(summary: CampaignSummary) -> str:
        ran = (f"{stored_at_start} stored before, {summary.runs - stored_at_start} run now"
               if stored_at_start else "all run now")
        return (f"{counted(summary.runs, 'run')} of spec {spec.name} (seed {seed}{screen}; "
                f"{ran}, {time.perf_counter() - started:.0f} s): {_counts(progress)}")

    _, line = _write_outputs(out, spec.name, plan.runs, said)
    click.echo(line)
    click.echo(f"Results: {out / 'results.sqlite'}  JUnit: {out / 'junit.xml'}  "
               f"Report: {out / 'report.html'}")


def _write_outputs(out: Path, name: str, runs: int,
                   text: Callable[[CampaignSummary], str]) -> tuple[int, str]:
    """junit.xml and report.html of every run stored in `out` (up to `runs`), under the line
    `text` makes of their summary; returns how many runs are stored, and that line."""
    with ResultStore(out / "results.sqlite") as store:
        summary = summarize(store.iter_rows(runs))
        try:
            write_junit(out / "junit.xml", name, store.iter_rows(runs), summary)
            line = text(summary)
            write_report(out / "report.html", name, summary, out, line)
        except OSError as exc:
            raise ScenarioOutputError(f"{out}: cannot write the report ({exc})") from exc
    return summary.runs, line


def _notable(source: Path, out: Path, runs: int | None,
             seed: int) -> tuple[dict[str, dict[str, Any]], int]:
    """The runs `--only-notable SOURCE` names (`compare.is_notable`), by id, and the --runs that
    covers them (`runs`, or by default the least that does); refused in one line when SOURCE is
    --out itself, cannot be read, is a campaign of another seed, holds none, or names runs
    beyond --runs."""
    if results_in(source).resolve() == (out / "results.sqlite").resolve():
        raise UsageError(f"--only-notable {source}: the same folder as --out; expected another "
                         "--out for the screen (then lanewarden compare the two)")
    try:
        with ResultStore(results_in(source), read_only=True) as store:
            stored_seed = store.identity().get("seed")
            if stored_seed is not None and stored_seed != str(seed):
                raise UsageError(f"--only-notable {source}: a campaign of seed {stored_seed}, "
                                 f"this one --seed {seed}; expected --seed {stored_seed} (the "
                                 "same spec and seed draw the same runs)")
            notable = {str(row["id"]): row for row in store.iter_rows() if is_notable(row)}
    except ScenarioError as exc:
        raise UsageError(f"--only-notable {source}: {exc}") from None
    if not notable:
        raise UsageError(f"--only-notable {source}: no run there is unsafe, a false halt, on a "
                         f"false lane or within {NEAR_TAPE_M * 1000:.0f} mm of a tape: nothing to "
                         "screen")
    last = max(notable, key=lambda run_id: int(run_id[1:]))
    covers = int(last[1:]) + 1
    if runs is not None and runs < covers:
        raise UsageError(f"--runs {runs}: --only-notable {source} names runs up to {last}; "
                         f"expected --runs {covers} or more (or no --runs)")
    return notable, covers if runs is None else runs


def _same_draws(plan: CampaignPlan, source: Path, notable: dict[str, dict[str, Any]]) -> None:
    """UsageError when a run `--only-notable` names is not drawn here as SOURCE holds it (another
    spec): the screen would run other runs under the same ids."""
    for run_id in sorted(notable):
        drawn = case_columns(draw_case(plan.spec, plan.spec_path, plan.seed, int(run_id[1:]),
                                       plan.config_overrides, plan.follow_speed_m_s))
        k = drawn_difference(notable[run_id], drawn)
        if k is not None:
            raise UsageError(f"--only-notable {source}: {run_id} there is not the run this spec "
                             f"draws ({k}: {notable[run_id].get(k)!r} there, {drawn.get(k)!r} "
                             "here); expected a campaign of the same spec and seed")


def _check_scheduler_address(address: str, named: str) -> None:
    """UsageError (one line naming the flag or variable) for a scheduler address Dask cannot
    parse ('foo', 'host:port-name'); it had raised a traceback from deep in Dask."""
    from distributed.comm.addressing import parse_address, parse_host_port

    try:
        protocol, location = parse_address(address)
        if protocol in ("tcp", "tls"):
            parse_host_port(location)
    except (ValueError, TypeError) as exc:
        raise UsageError(f"{named} {address!r}: not a scheduler address ({exc}); expected "
                         f"tcp://HOST:PORT (a Dask scheduler), {LOCAL} or {IN_PROCESS}") from None


def commands() -> list[click.Command]:
    return [campaign_command]


__all__ = ["IN_PROCESS", "commands"]
