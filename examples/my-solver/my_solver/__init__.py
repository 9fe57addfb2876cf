"""my-solver: a small constrained-dynamics solver (RATTLE) and its xval adapter.

``my_solver.rattle`` is the solver (numpy only); ``my_solver.xval_adapter``
is the adapter xval finds through the ``xval.engines`` entry point.
"""

__version__ = "0.1.0"
