"""The dense layer"""
