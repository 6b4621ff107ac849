"""Benchmark scripts (run as ``python benchmarks/bench_*.py``) and the generated scene family (``benchmarks.scenes``),
importable by tests and benchmarks alike."""
