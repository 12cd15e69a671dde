"""Performance: level-of-detail scene benchmark and cost-growth charts (issue 7)."""
