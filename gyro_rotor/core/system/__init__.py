"""Rotor systems of the general theory: system files, generated equations, scenes."""
