"""Input encodings: NeRF's frequencies, triangle waves, spherical harmonics"""
