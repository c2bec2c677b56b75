"""Elementwise functions, one lane in, one lane out"""
