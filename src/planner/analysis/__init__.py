"""Design analysis of the hybrid manipulator: workspace volume, sections, singularity loci,
isoconditioning curves, design checks and design optimisation (numpy/scipy only)."""

__all__ = []
