"""The papers inshade implements, cited by title, venue and arXiv id or DOI (README, records, reports)."""
from inshade.technique import Paper

DIFFERENTIABLE_INDIRECTION = Paper("Efficient Graphics Representation with Differentiable Indirection",
                                   "SIGGRAPH Asia 2023", arxiv="2309.08387", doi="10.1145/3610548.3618203")
NEURAL_APPEARANCE = Paper("Real-Time Neural Appearance Models", "ACM Transactions on Graphics 2024",
                          arxiv="2305.02678")
LEARNT_TRANSFER = Paper("Real-Time Rendering of Arbitrary Surface Geometries using Learnt Transfer", "ICVGIP 2022",
                        doi="10.1145/3571600.3571640")
FEATURE_HIERARCHY = Paper("Neural Compression of Material Properties using a Geometry-Associated Feature Hierarchy",
                          "Master's thesis, Chalmers University of Technology 2024")
APPEARANCE_PREFILTERING = Paper("Deep Appearance Prefiltering", "ACM Transactions on Graphics 2023",
                                arxiv="2211.05932", doi="10.1145/3570327")
