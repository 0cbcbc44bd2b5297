"""Resampling between layouts and sizes, ∫L dω kept: the compiled kernel and each mechanism it relies on, one module each (see docs/resampling.md)."""
