"""tiny-cuda-nn's OneBlob encoding"""
