"""Foundations every floor stands on: errors, the names users type, limits, progress, atomic files, numba."""
