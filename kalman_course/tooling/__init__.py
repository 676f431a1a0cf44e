"""Course tooling, the top layer: authoring, grading, review, export, notebook execution,
the benchmark report and the command line. May import every other layer.
"""
