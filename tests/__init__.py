"""mpsbench test suite."""
