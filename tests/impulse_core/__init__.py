"""Tests of impulse_core."""
