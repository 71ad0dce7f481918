"""``python -m fccgen ...``: the same as the ``fccgen`` command."""
import sys

from .cli import main

sys.exit(main())
