"""pytest plugin. Placeholder."""
