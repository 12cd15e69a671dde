"""Performance: level-of-detail levers, cost growth, rate and latency benchmarks, soak and scale-out (issue 7)."""
