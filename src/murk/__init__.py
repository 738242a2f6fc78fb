"""murk: underwater robots seeing construction sites through murky water.

Realistic synthetic underwater data (Jerlov absorption and backscatter, depth-dependent forward scattering,
marine snow cut from real footage), Joint-ID restoration with HE + LoG post-processing, and underwater image
quality metrics that reproduce the published codebases.

Source paper: Yun, Yang, Lee, Park, Choi, Cho, "Robust Image Processing Techniques for Construction
Environment Monitoring Using Underwater Robots".
"""

from murk._version import __version__

__all__ = ["__version__"]
