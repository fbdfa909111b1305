"""Outputs layer: figures, JSON files and reports built from analysis results."""
