"""The case record and everything read from it: measuring a case, metrics, the sweep, the verdict, the tables."""
