"""Benchmarks: one script per hot path, each printing a table (``python -m benchmarks.<name>``)."""
