"""paramotion: what all robots share (graph runner, sim clock, bags, CLI, shared geometry)."""
