"""Test oracles and physics checks of the runtime model: the NumPy references of the numba kernels
(:mod:`.reference`, :mod:`.needle_reference`) and the physics checks of the tissue forms (:mod:`.physics`)."""
