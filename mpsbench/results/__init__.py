"""Results: run records and their identity, sweeps and executors, study files, comparison
against a baseline, and the report folder (case reports, summary.md, index.html)."""
