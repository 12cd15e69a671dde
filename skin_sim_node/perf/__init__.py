"""Performance benchmarks and charts (issue 7)."""
