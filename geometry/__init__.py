"""Geometry sources: procedural meshes and shapes (the teapot, tori, the bunny), mesh loading
and topology, and analytic SDF scenes: what trainers fit and scenes draw."""
