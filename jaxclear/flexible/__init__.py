"""Flexible links: planar beams in the absolute nodal coordinate formulation (ANCF cable
elements), their supports, statics, natural frequencies and motion (docs/theory/flexible-links.md)."""
