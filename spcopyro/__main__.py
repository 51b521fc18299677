"""``python -m spcopyro ...``: the ``spcopyro`` command."""

from spcopyro.cli import console_main

console_main()
