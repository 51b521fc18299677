"""``python -m spcopyro ...``: the ``spcopyro`` command."""

from spcopyro.cli.main import console_main

console_main()
