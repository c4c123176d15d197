"""``python -m uvdms_cli``: the ``uvdms`` command."""

from uvdms_cli.main import main

raise SystemExit(main())
