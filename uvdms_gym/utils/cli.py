"""Command-line helpers shared by ``uvdms`` and ``python -m agents.training.train``: argument errors in one line.

argparse prints the usage and an error over several lines; the project's commands promise one line,
``uvdms: error: <what is wrong>``, and exit status 2. :class:`OneLineArgumentParser` does that for argument
errors (an unknown option, a value of the wrong type); subcommand parsers inherit it (``add_subparsers`` uses the
parent's class).
"""

from __future__ import annotations

import argparse
from typing import NoReturn


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

    def error(self, message: str) -> NoReturn:
        """Print ``<command>: error: <message> (<prog> --help)`` on one line and exit with status 2."""
        command = self.command or self.prog.split()[0]
        self.exit(2, f"{command}: error: {' '.join(message.split())} (see {self.prog} --help)\n")
