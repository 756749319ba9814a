"""``python -m optimizer``: the ``footopt`` command line."""

from optimizer.cli.entry import main

raise SystemExit(main())
