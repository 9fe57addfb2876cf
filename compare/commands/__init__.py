"""The ``xval`` commands, one module per verb: each parses its options and calls one stage of compare."""
