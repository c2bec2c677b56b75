"""Learned shading frames (Real-Time Neural Appearance Models, Eq. 7)"""
