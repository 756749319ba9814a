"""``python -m optimizer``: the ``footopt`` command line."""

from optimizer.cli.main import main

raise SystemExit(main())
