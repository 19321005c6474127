"""``python -m viz3d`` is the ``viz3d`` command."""

from viz3d.cli import main

raise SystemExit(main())
