"""Maintainer tools run from a source checkout (``python -m scripts.<name>``); not part of the installed library."""
