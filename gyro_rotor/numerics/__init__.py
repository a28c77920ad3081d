"""Numerics: integrators, simulate, ensemble, real-time pacing and benchmarks (pure)."""
