"""Searches over foot designs: inner (IPOPT per shape) and outer (Optuna)."""
