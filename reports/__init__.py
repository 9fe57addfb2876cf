"""reports: one self-contained HTML file per results directory (``xval report DIR``); docs/report.md explains it.

- :mod:`reports.load`: read a results directory (through ``compare``) and arrange it by scene and variant.
- :mod:`reports.verdict`: the first section, per scene (from :mod:`compare.results.verdict`): Pareto front,
  cost to reach 1e-6·L, the focus family against the best other, stability heat map, problems.
- :mod:`reports.svgplot`: the verdict's log–log plot as inline SVG (no plotly.js needed to see it).
- :mod:`reports.summary`: the per-scene summary tables (one per dt) and their best-value marks.
- :mod:`reports.figures`: the per-scene plots as plotly.js figure specs (clipped blow-ups, thinned traces).
- :mod:`reports.animation`: the data of a scene's canvas animation.
- :mod:`reports.palette`: one hue per engine family, shades per variant, the same in every report.
- :mod:`reports.decimate`: largest-triangle-three-buckets, at most 2,000 points a trace.
- :mod:`reports.stability`: the stability search and gain-map sections.
- :mod:`reports.render`: the Jinja2 page (``templates/report.html.j2``); plotly.js and the figure data
  packed (gzip as 7-bit text, reports/pack.py) and unpacked by the browser when a section is opened.
- :mod:`reports.cli`: the ``report`` verb, added to ``xval`` through the ``xval.commands`` entry point.

Imports go one way: reports uses compare and engines; nothing imports reports.
"""
