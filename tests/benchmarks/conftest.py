"""The pytest-benchmark suite stores mpsbench's provenance with its results.

``pytest tests/benchmarks --benchmark-only --benchmark-autosave`` writes
``.benchmarks/<machine id>/<NNNN>_<commit>_<time>[_uncommitted-changes].json`` with
pytest-benchmark's ``machine_info`` (CPU, Python, node) and ``commit_info`` (commit, dirty);
this hook adds ``machine_info["mpsbench"]``: the environment every mpsbench record carries
(docs/columns.md: versions of numpy/scipy/numba/pandas, CPU model and cores, mpsbench's commit
and dirty flag) with each backend's version and commit, and the load average at the end.
``mpsbench bench --save`` writes its runs into the same storage in the same layout.
"""

from __future__ import annotations

import os
from typing import Any


def pytest_benchmark_update_machine_info(config: Any, machine_info: dict[str, Any]) -> None:
    from mpsbench.results.records import environment
    from mpsbench.run.protocol import SOLVERS

    machine_info["mpsbench"] = {**environment(SOLVERS.names()),
                                "load_avg_end": round(os.getloadavg()[0], 2)}
