"""Benchmarks shipped with the package so that ``pickplace bench NAME`` runs them from any install.

``benchmarks/NAME.py`` at the repository root are thin wrappers around these modules.
"""
