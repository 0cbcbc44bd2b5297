"""Rendering: scenes lit by an environment map, the project's renderer with pluggable lighting methods, and a
Mitsuba 3 ground truth to measure every method against."""
