"""Benchmark scripts: print timing numbers of core components; no assertions, not run by tests."""
