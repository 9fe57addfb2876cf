"""History: every finished run kept, append-only, in one store (a SQLite file, or PostgreSQL).

- :mod:`compare.history.store`: the store (schema versioned and migrated,
  several writers at once, a run added twice refused, stored runs never changed).
- :mod:`compare.history.origin`: what a run is tied to (commit, dirty flag, machine fingerprint).
- :mod:`compare.history.trend`: per scene × variant × dt series across runs, and step changes in them.
- :mod:`compare.history.window`: the gate against the last N runs on the same machine.

docs/history.md describes the commands (``xval history add | show | report``,
``xval run --history``, ``xval gate --history``).
"""
