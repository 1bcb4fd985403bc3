"""Measuring the stack: campaigns of randomized episodes (local or Ray), reports and plots, benchmarks."""
