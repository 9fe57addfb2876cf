"""reports: one self-contained HTML file per results directory (``xval report DIR``); docs/report.md explains it.

Modules: ``load`` (a results directory by scene and variant), ``verdict``, ``svgplot``, ``summary``,
``figures``, ``animation``, ``palette``, ``decimate``, ``stability`` (the page's sections and their
parts), ``render`` (the Jinja2 page), ``cli`` (the ``report`` verb). Imports go one way: reports uses
compare and engines; nothing imports reports.

Details: docs/report.md, "Module notes", ``reports/__init__.py``.
"""
