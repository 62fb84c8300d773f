"""Generation, what the backends stand on: targets (what to generate, from options or project configuration),
the backend interface (backend.py), in-memory trees → disk, atomically and without losing a user's work
(emit.py). The build that runs the backends is the compiler's (compiler/build.py).

Shared by every backend: the templating environment and the safe-literal helpers (textsafe.py).
"""
