"""coverage_pkg package."""
