"""Command-line helpers shared by ``uvdms`` and ``python -m agents.training.train``: argument errors in one line.

argparse prints the usage and an error over several lines; the project's commands promise one line,
``uvdms: error: <what is wrong>``, and exit status 2. :class:`OneLineArgumentParser` does that for argument
errors (an unknown option, a value of the wrong type); subcommand parsers inherit it (``add_subparsers`` uses the
parent's class). An option the parser does not know is named first, with the closest known one
(``unrecognized arguments: --controler (did you mean --controller?)``), even where argparse would have reported
a missing required option instead.
"""

from __future__ import annotations

import argparse
import difflib
import re
import sys
from collections.abc import Sequence
from typing import Any, NoReturn

_NUMBER = re.compile(r"^-\d+$|^-\d*\.\d+$")
"""Tokens argparse reads as negative numbers (values), not options."""


def _option_strings(parser: argparse.ArgumentParser) -> list[str]:
    return [s for action in parser._actions for s in action.option_strings]


def _subparsers(parser: argparse.ArgumentParser) -> dict[str, argparse.ArgumentParser]:
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            return dict(action.choices)
    return {}


def _is_known(parser: argparse.ArgumentParser, token: str) -> bool:
    """Whether ``parser`` takes ``token`` as one of its options, as argparse decides it.

    ``-vv`` is ``-v -v``, an abbreviation of a long option counts, ``-n5`` is ``-n 5``.
    """
    found = parser._parse_optional(token)  # None: not an option; (action, ...) or a list of such (Python >= 3.12.7)
    if found is None:
        return True
    tuples = found if isinstance(found, list) else [found]
    return any(t[0] is not None for t in tuples)


def unknown_options(parser: argparse.ArgumentParser, args: Sequence[str]) -> list[tuple[str, list[str], str]]:
    """The option tokens of ``args`` that ``parser`` (or the subcommand they follow) does not know.

    Returns:
        ``(token, the closest known option string (none or one), prog of the parser that does not know it)`` for
        each unknown option, in order.
    """
    options, commands = _option_strings(parser), _subparsers(parser)
    found: list[tuple[str, list[str], str]] = []
    for i, token in enumerate(args):
        if token == "--":
            break
        if token in commands:
            return found + unknown_options(commands[token], list(args)[i + 1 :])
        if token.startswith("-") and len(token) > 1 and not _NUMBER.match(token):
            name = token.split("=", 1)[0]
            if not _is_known(parser, token):
                found.append((name, difflib.get_close_matches(name, options, n=1, cutoff=0.6), parser.prog))
    return found


def unknown_options_message(unknown: list[tuple[str, list[str], str]]) -> str:
    """``unrecognized arguments: --controler (did you mean --controller?)``."""
    parts = [f"{token} (did you mean {' or '.join(close)}?)" if close else token for token, close, _ in unknown]
    return "unrecognized arguments: " + " ".join(parts)


class OneLineArgumentParser(argparse.ArgumentParser):
    """An ``ArgumentParser`` whose errors are one line, ``<command>: error: <message> (<prog> --help)``, exit 2.

    Args:
        *args: As :class:`argparse.ArgumentParser`.
        command: The name the error line starts with (default: the first word of ``prog``, e.g. ``uvdms``).
        **kwargs: As :class:`argparse.ArgumentParser`.
    """

    def __init__(self, *args: object, command: str | None = None, **kwargs: object) -> None:
        super().__init__(*args, **kwargs)  # type: ignore[arg-type]
        self.command = command
        self._parsed_args: list[str] = []

    def parse_known_args(self, args: Sequence[str] | None = None, namespace: Any = None) -> Any:
        """As :meth:`argparse.ArgumentParser.parse_known_args` (the arguments are kept for :meth:`error`)."""
        self._parsed_args = list(sys.argv[1:] if args is None else args)
        return super().parse_known_args(args, namespace)

    def error(self, message: str) -> NoReturn:
        """Print ``<command>: error: <message> (<prog> --help)`` on one line and exit with status 2.

        An unknown option among the arguments is the error reported (with the closest known option).
        """
        unknown, prog = unknown_options(self, self._parsed_args), self.prog
        if unknown:
            message, prog = unknown_options_message(unknown), unknown[0][2]
        command = self.command or self.prog.split()[0]
        self.exit(2, f"{command}: error: {' '.join(message.split())} (see {prog} --help)\n")
