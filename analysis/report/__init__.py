"""The analysis report of a stiffness campaign: data assembly, plots, HTML and PDF.

:func:`analysis.report.build.build_report` assembles a :class:`~analysis.report.document.Report`
(sections of paragraphs, tables and figures, numbers already formatted with
their units) from an identification result; :mod:`analysis.report.html` and
:mod:`analysis.report.pdf` render that one structure, so both files show the
same numbers.
"""
