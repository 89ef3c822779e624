"""Figures a person looks at (PNG files): matplotlib only, imported on demand."""
