"""Experiments: protocol files, sessions with subjects, scripted subjects, sweeps and reports (docs/experiments.md)."""
