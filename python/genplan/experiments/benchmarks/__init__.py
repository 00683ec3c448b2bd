"""Benchmarks behind ``genplan bench ...``: each prints its table and writes JSON."""
