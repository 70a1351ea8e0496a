"""Private runtime helpers: forked half-jobs, memory release of long runs, the OpenSim peer in a
child process."""

__all__: list[str] = []
