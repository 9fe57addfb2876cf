"""The home of ours' adapter: the adapter, and ours' rigid bodies built from a model description (the solver
library itself is the top-level package ours)."""
