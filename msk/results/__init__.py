"""The results contract: the typed ``summary.json`` and the results folder ``msk run`` writes, read
back typed."""

__all__: list[str] = []
