"""``python -m spcopyro ...``: the ``spcopyro`` command."""

from spcopyro.cli.main import console_main

if __name__ == "__main__":  # imported (e.g. by the docs' API reference), it runs nothing
    console_main()
