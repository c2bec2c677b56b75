"""Sparse multi-scale voxel latents (Deep Appearance Prefiltering, Bako et al. 2022)"""
