"""Running a suite's cases in case hosts (local or on Dask), writing their records, and reading a run back."""
