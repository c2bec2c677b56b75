"""The importance-sampling proxy's output activation (Real-Time Neural Appearance Models)"""
