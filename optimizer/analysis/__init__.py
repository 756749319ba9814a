"""Benchmarks and accuracy/sensitivity studies behind footopt bench."""
