"""A click group that answers a mistyped subcommand with the closest name ("did you mean").

Click lists no alternatives for an unknown subcommand; this group names the closest one
(difflib) or, failing that, all of them. Used by the `lanewarden` root and its groups.
"""

from __future__ import annotations

import difflib

import click


def unknown_command_message(name: str, known: list[str]) -> str:
    """"No such command 'cailbrate'; did you mean 'calibrate'?" (or the list of commands)."""
    close = difflib.get_close_matches(name, known, n=1)
    if close:
        return f"No such command '{name}'; did you mean '{close[0]}'?"
    return f"No such command '{name}' (expected one of: {', '.join(known)})"


class CommandGroup(click.Group):
    def resolve_command(
        self, ctx: click.Context, args: list[str]
    ) -> tuple[str | None, click.Command | None, list[str]]:
        name = args[0] if args else ""
        if name and not name.startswith("-") and self.get_command(ctx, name) is None:
            raise click.UsageError(unknown_command_message(name, self.list_commands(ctx)), ctx)
        return super().resolve_command(ctx, args)
