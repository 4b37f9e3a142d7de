"""Headless reproduction of the STNS paper's experiments with baselines, plots and reports."""
