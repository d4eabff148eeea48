"""The command table of ``afo-mj`` (:data:`afo_mj.cli.COMMANDS`) against its grammar
(:func:`afo_mj.cli_args.build_parser`): the same commands, each dispatched to its handler."""

from __future__ import annotations

import argparse
import inspect

import pytest

from afo_mj import cli
from afo_mj.cli_args import build_parser


def _subcommands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    (sub,) = [a for a in parser._actions if isinstance(a, argparse._SubParsersAction)]
    return dict(sub.choices)


def test_table_and_parser_declare_the_same_commands():
    parser = build_parser(cli.COMMANDS, "0")
    assert sorted(_subcommands(parser)) == sorted(cli.COMMANDS)


def test_every_command_dispatches_to_its_own_handler():
    subs = _subcommands(build_parser(cli.COMMANDS, "0"))
    for name, handler in cli.COMMANDS.items():
        # the handler is a function of afo_mj.cli taking the parsed arguments
        assert inspect.isfunction(handler) and handler.__module__ == "afo_mj.cli", name
        assert getattr(cli, handler.__name__) is handler, name
        assert len(inspect.signature(handler).parameters) == 1, name
        assert subs[name].get_default("func") is handler, name
    # no handler is shared by two commands
    assert len({id(h) for h in cli.COMMANDS.values()}) == len(cli.COMMANDS)


def test_parsed_command_line_carries_its_handler():
    parser = build_parser(cli.COMMANDS, "0")
    args = parser.parse_args(["build-models"])
    assert args.command == "build-models" and args.func is cli.COMMANDS["build-models"]
    args = parser.parse_args(["hydraulics-demo", "--duration-s", "0.5"])
    assert args.func is cli.COMMANDS["hydraulics-demo"] and args.duration_s == 0.5


def test_a_table_missing_a_command_is_refused_by_the_parser():
    handlers = {k: v for k, v in cli.COMMANDS.items() if k != "schematic"}
    with pytest.raises(KeyError, match="schematic"):
        build_parser(handlers, "0")


def test_the_commands_that_write_all_or_nothing_are_commands():
    """An interrupted run, render, compare or demo says "nothing written": each name in that
    list is a command as typed (the demo was listed as "demo", which no command is)."""
    from afo_mj import cli
    assert set(cli._ATOMIC) <= set(cli.COMMANDS)
