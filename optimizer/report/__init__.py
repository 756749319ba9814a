"""Text reports and plots."""
