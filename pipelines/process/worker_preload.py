"""Imported once by the frame workers' fork server (:func:`pipelines.process.frames._context`)
before it forks a worker: numpy, OpenCV, vision and the measurement's compiled kernels
(:func:`vision.jit.load_cached`) are then in every worker from its first instruction,
loaded once per run instead of once per worker (~0.3 s of imports and ~0.4 s of kernels
each). A fork server is a fresh interpreter with no thread of the caller's (Rerun's, the
log reader's), so forking it is safe where forking the caller is not."""

from __future__ import annotations

from pipelines.process import frames  # noqa: F401  (what a worker runs, and its imports)
from vision.jit import load_cached

load_cached()
