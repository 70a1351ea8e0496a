"""``python -m msk.cli``: the ``msk`` command."""

from msk.cli import console

console()
