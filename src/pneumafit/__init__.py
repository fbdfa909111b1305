"""pneumafit."""
