"""``python -m spcopyro ...``: the ``spcopyro`` command."""

import sys

from spcopyro.cli import main

sys.exit(main())
