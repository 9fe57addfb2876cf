"""xval's harness, one folder per stage: suites read, cases run in hosts and measured, records stored,
gated, kept in a history, searched for stability; ``compare.cli`` is the ``xval`` program."""
