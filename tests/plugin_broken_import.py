"""A plugin module whose import fails (its solver library is missing): for tests/test_plugins.py.

Named in suites as ``plugin_broken_import:ENGINE``; xval must record it as
unavailable, with the plugin's name and the import error, and run the rest.
"""

import xval_test_no_such_solver_library  # noqa: F401  (deliberately missing)

ENGINE = None
