"""The parser of one command is built alone (the others' cost milliseconds of every start-up),
and parses and explains that command exactly as the parser of every command does."""

from __future__ import annotations

import argparse

import pytest

from foldfab.cli import GROUPS, build_parser


def commands(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    """The parser of each command ``parser`` knows."""
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    return dict(sub.choices)


def test_every_command_is_in_the_table_of_its_group():
    assert list(commands(build_parser())) == list(GROUPS)
    for group in set(GROUPS.values()):
        parser = argparse.ArgumentParser(prog="foldfab")
        group.add_commands(parser.add_subparsers())
        assert set(commands(parser)) == {name for name, module in GROUPS.items() if module is group}


@pytest.mark.parametrize("name", list(GROUPS))
def test_a_command_parser_alone_is_the_same_command(name):
    alone, whole = commands(build_parser(name)), commands(build_parser())
    assert set(alone) == {n for n, module in GROUPS.items() if module is GROUPS[name]}
    assert alone[name].format_help() == whole[name].format_help()
    assert alone[name].format_usage() == whole[name].format_usage()


@pytest.mark.parametrize("argv", [["--help"], ["expor"], ["--version"], []])
def test_no_command_name_builds_every_command(argv, capsys):
    """--help lists every command; a misspelt one is told the choices."""
    from foldfab.cli import main

    with pytest.raises(SystemExit):
        main(argv)
    out = capsys.readouterr()
    if argv and argv[0] != "--version":
        assert all(name in out.out + out.err for name in GROUPS)
