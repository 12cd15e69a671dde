"""skin-sim: layered skin haptic simulation. The model core is :mod:`skin_sim_node.model`."""

__version__ = "0.1.0"
