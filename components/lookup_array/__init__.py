"""Differentiable Indirection's lookup arrays"""
