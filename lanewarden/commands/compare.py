"""`lanewarden compare`: two campaigns of the same draws, run by run (what a change did).

Thin shell: open both results databases for reading only (nothing in either folder is written),
compare them (`scenarios.campaign.compare`), print the table and the runs that changed, worse
first. `--fail-if-worse` makes it a gate: exit 3 (a safety verdict, as `survey`'s NOT SAFE) when
a run became unsafe or a false halt, so a CI job tells "worse" from a comparison that could not
be made (exit 2).
"""

from __future__ import annotations

import json
from pathlib import Path

import click

from lanewarden.commands.flags import PathFlag
from lanewarden.errors import EXIT_OK, EXIT_SAFETY_STOP
from lanewarden.scenarios.campaign.compare import (
    CampaignsDiffer,
    as_json,
    compare_campaigns,
    describe,
)
from lanewarden.scenarios.campaign.store import ResultStore, results_in
from lanewarden.wording import counted

EXAMPLES = """\b
Examples:
  lanewarden campaign --spec default --runs 300 --seed 4 --out before
  lanewarden campaign --spec default --runs 300 --seed 4 --out after --config mine.yaml
  lanewarden compare before after
  lanewarden compare before after --fail-if-worse
"""


@click.command("compare", epilog=EXAMPLES)
@click.argument("before", type=PathFlag("a campaign's --out folder"))
@click.argument("after", type=PathFlag("a campaign's --out folder"))
@click.option("--json", "as_json_flag", is_flag=True,
              help="Print one JSON object (the comparison, every changed run) instead of the "
              "table.")
@click.option("--fail-if-worse", is_flag=True,
              help="Exit 3 when a run became unsafe or a false halt in AFTER (2: the two could "
              "not be compared).")
def compare_command(before: str, after: str, as_json_flag: bool, fail_if_worse: bool) -> int:
    """Compare two campaigns of the same spec and seed run by run (AFTER: with a changed
    --config, say): outcomes, closest approaches to a tape, false lanes, and every run whose
    outcome changed, worse first. Reads both folders, writes nothing."""
    with (ResultStore(results_in(Path(before)), read_only=True) as old,
          ResultStore(results_in(Path(after)), read_only=True) as new):
        seeds = old.identity().get("seed"), new.identity().get("seed")
        if None not in seeds and seeds[0] != seeds[1]:
            raise CampaignsDiffer(f"{before} holds a campaign of seed {seeds[0]}, {after} one of "
                                  f"seed {seeds[1]}: runs are compared by id, so both must come "
                                  "from the same spec and seed (only --config may differ)")
        comparison = compare_campaigns(old.iter_rows(), new.iter_rows(), (before, after))
    if as_json_flag:
        click.echo(json.dumps(as_json(comparison, before, after)))
    else:
        for line in describe(comparison, before, after):
            click.echo(line)
    worse = comparison.of("worse")
    if fail_if_worse and worse:
        named = ", ".join(f"{r.run_id} ({r.before} -> {r.after})" for r in worse[:5])
        more = f" and {len(worse) - 5} more" if len(worse) > 5 else ""
        click.echo(f"lanewarden: worse: {counted(len(worse), 'run')} got worse in {after}: "
                   f"{named}{more}", err=True)
        return EXIT_SAFETY_STOP
    return EXIT_OK


def commands() -> list[click.Command]:
    return [compare_command]
