"""Ops along the feature axis: constants, lane selection, branches, integer gathers, reductions, normalisation, the residual add"""
