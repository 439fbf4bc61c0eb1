"""An integer flag refuses a value that is no integer, or lies outside its range, in one line
naming the flag, the value and the range expected, as the config says it of an integer key; exit
2. click's own words had been "'abc' is not a valid integer range" (a new user's review)."""

from __future__ import annotations

from collections.abc import Iterator

import click
import pytest

from lanewarden.cli import cli, main
from lanewarden.commands.flags import WholeRange


def integer_options(command: click.Command, words: tuple[str, ...] = ()
                    ) -> Iterator[tuple[tuple[str, ...], click.Option]]:
    """(the command's words, an option) for every option that takes an integer."""
    for param in command.params:
        if isinstance(param, click.Option) and isinstance(param.type, click.types.IntParamType):
            yield words, param
    if isinstance(command, click.Group):
        for name, sub in command.commands.items():
            yield from integer_options(sub, (*words, name))


INTEGER_OPTIONS = list(integer_options(cli))


def test_every_integer_option_is_a_whole_range() -> None:
    found = {(" ".join(words), param.opts[0]) for words, param in INTEGER_OPTIONS}
    assert {("survey", "--jitter"), ("campaign", "--runs"), ("sim", "--seed")} <= found
    for words, param in INTEGER_OPTIONS:
        assert isinstance(param.type, WholeRange), (words, param.opts[0])


@pytest.mark.parametrize(("words", "param"), INTEGER_OPTIONS,
                         ids=[f"{' '.join(w)} {p.opts[0]}" for w, p in INTEGER_OPTIONS])
def test_a_bad_integer_is_one_line_exit_2(words: tuple[str, ...], param: click.Option,
                                          capsys: pytest.CaptureFixture[str]) -> None:
    low, high = param.type.min, param.type.max  # type: ignore[attr-defined]
    for given in ("abc", "2.5", str(high + 1), str(low - 1)):
        code = main([*words, param.opts[0], given])
        err = capsys.readouterr().err
        assert code == 2, err
        assert err.count("\n") == 1, err
        assert err.rstrip().endswith(
            f"Invalid value for '{param.opts[0]}': {given}: expected an integer with "
            f"{low} <= value <= {high}"), err


def test_the_jitter_line_in_full(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["survey", "somewhere", "--jitter", "abc"]) == 2
    assert capsys.readouterr().err == (
        "lanewarden: error: lanewarden survey: Invalid value for '--jitter': abc: expected an "
        "integer with 0 <= value <= 64\n")
    # an empty value is named as such (it had read "'--jitter': : expected")
    assert main(["survey", "somewhere", "--jitter", ""]) == 2
    assert capsys.readouterr().err == (
        "lanewarden: error: lanewarden survey: Invalid value for '--jitter': '': expected an "
        "integer with 0 <= value <= 64\n")
