"""Geometry: the rigid composite surface h on the grid (README.md, "Layout").

``surfaces`` (arrays, files, spheres, self-affine random surfaces) and ``tips`` (atomic-scale
tips, docs/studies.md "3.3 Atomic-scale contact").
"""
