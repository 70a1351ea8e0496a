"""Private runtime helpers: the stage cache, forked half-jobs, frame blocks and memory release of
long runs, the OpenSim peer in a child process."""

__all__: list[str] = []
