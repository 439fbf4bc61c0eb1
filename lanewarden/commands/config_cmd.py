"""`lanewarden config show`: print the effective configuration."""

from __future__ import annotations

import click

from lanewarden.commands.command_group import CommandGroup
from lanewarden.commands.flags import PathFlag
from lanewarden.config import config_as_yaml, load_config


def config_option(func: click.decorators.FC) -> click.decorators.FC:
    """The shared `--config FILE` option (a missing file is refused here, naming the flag)."""
    return click.option(
        "--config", "config_path", type=PathFlag("a config file", dir_okay=True, exists=True),
        default=None,
        help="YAML config file (default: built-in defaults; see `lanewarden config show`).",
    )(func)


@click.group("config", cls=CommandGroup)
def config_group() -> None:
    """Inspect the configuration."""


@config_group.command("show")
@config_option
def show(config_path: str | None) -> None:
    """Print the effective config (defaults merged with FILE) as YAML."""
    click.echo(config_as_yaml(load_config(config_path)), nl=False)


def commands() -> list[click.Command]:
    return [config_group]
