"""``python -m servoid`` runs the command line."""

from servoid.cli import main

raise SystemExit(main())
