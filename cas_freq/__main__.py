"""``python -m cas_freq`` runs the command-line interface."""

from cas_freq.cli import main

raise SystemExit(main())
