"""The ``spcopyro`` command line: :mod:`~spcopyro.cli.main` parses and dispatches; each command
with its own module (``fit``, ``export``, ``navigate``, ``study``) and shared argument helpers in
:mod:`~spcopyro.cli.common`. Commands that only read a saved fit import neither torch nor pyro."""
