"""Plots: the only package that imports matplotlib (demo figures, fixed-point error maps)."""
