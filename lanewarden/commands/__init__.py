"""The CLI's command groups, one module each. Each module exposes `command` (a click command)."""

from __future__ import annotations

import click


def register_commands(cli: click.Group) -> None:
    from lanewarden.commands import (
        base,
        calibrate,
        campaign,
        compare,
        config_cmd,
        detect,
        replay,
        run,
        sim,
        survey,
        undistort,
    )

    for module in (config_cmd, detect, calibrate, undistort, base, sim, run, replay, survey,
                   campaign, compare):
        for command in module.commands():
            cli.add_command(command)
