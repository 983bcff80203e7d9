"""Full screens (Main; Setup comes with its own issue)."""
