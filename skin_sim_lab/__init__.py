"""The skin-sim lab: benchmarks (:mod:`.perf`), FEM references and accuracy checks (:mod:`.validation`), stability
studies (:mod:`.stability`), baseline solvers (:mod:`.solvers`), figures (:mod:`.viz`) and the NumPy oracles and
physics checks of the model (:mod:`.oracles`).

Not the runtime: the lab imports :mod:`skin_sim_node` (the server) and :mod:`msgs_schema` (the contract); neither
imports anything from here (tests/test_architecture.py). Most of it needs the ``lab`` extra (pyproject.toml). Its
commands run through ``skin-sim`` (:mod:`skin_sim_node.cli` names them as strings).
"""
