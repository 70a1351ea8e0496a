"""Helpers shared by several test modules (``from tests.support.<module> import ...``).

Test modules never import each other: what two of them need lives here, or in msk itself when
it is useful beyond the tests (synthetic models and trials: :mod:`msk.datasets.models`,
:mod:`msk.datasets.trials`; the OpenSim subject01 walk: :mod:`msk.datasets.opensim_subject01`).
``bench/`` never imports from ``tests/``. The repository root is on ``sys.path`` through
pytest's ``pythonpath`` setting (``pyproject.toml``).
"""
