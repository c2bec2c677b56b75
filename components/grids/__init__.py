"""Multiresolution grid encodings (instant-NGP; inshade/grid_layout.py has the rules)"""
