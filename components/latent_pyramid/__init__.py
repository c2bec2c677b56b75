"""Latent texture pyramids (Real-Time Neural Appearance Models)"""
