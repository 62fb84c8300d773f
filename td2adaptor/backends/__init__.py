"""The backends: one folder each, found by `registry.py` beside them; `generation.backend` is the interface.

A backend folder holds its generator code, `templates/` (Jinja2, only what varies) and `verbatim/` (files
copied into the output unchanged; real source files that this repository's lint and type checks read).
"""
