"""``python -m contactpetsc``: the ``contactpetsc`` command (``app.cli``)."""
import sys

from .app.cli import main

sys.exit(main())
