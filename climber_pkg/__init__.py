"""climber_pkg package."""
