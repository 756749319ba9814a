"""Pareto fronts and run directories."""
