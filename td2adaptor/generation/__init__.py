"""Generation: targets (what to generate, from options or project configuration) → backends (found by the
registry) → in-memory trees → disk, atomically and without losing a user's work (emit.py).

Shared by every backend: the templating environment and the safe-literal helpers (textsafe.py).
"""
