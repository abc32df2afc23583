"""Running a solver: the registry-facing Solver protocol and capabilities, the runner that owns
the time loop, probes that observe it, and the throughput benchmark."""
