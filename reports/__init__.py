"""reports: one self-contained HTML file per results directory (``xval report DIR``).

- :mod:`reports.load`: read a results directory (through ``compare``) and arrange it by scene and variant.
- :mod:`reports.summary`: the per-scene summary table and its best-value marks.
- :mod:`reports.figures`: the per-scene plots as plotly.js figure specs.
- :mod:`reports.render`: the Jinja2 page (``templates/report.html.j2``) with plotly.js inlined once.
- :mod:`reports.cli`: the ``report`` verb, added to ``xval`` through the ``xval.commands`` entry point.

Imports go one way: reports uses compare and engines; nothing imports reports.
"""
