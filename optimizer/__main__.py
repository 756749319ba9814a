"""``python -m optimizer``: the ``footopt`` command line."""

from optimizer.cli import main

raise SystemExit(main())
