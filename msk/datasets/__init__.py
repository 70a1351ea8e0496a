"""Sample, synthetic and reference data generators (known-truth trials, models, tasks; the shared
recordings'
location). Used by tests, benchmarks, examples and studies; no algorithm lives here."""

__all__: list[str] = []
