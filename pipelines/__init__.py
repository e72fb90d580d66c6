"""beambench pipelines: the synthetic bench, capture, replay, processing, results,
Rerun review and the ``beambench`` command line. Imports ``sim``, ``vision`` and
``daq``; nothing imports ``pipelines``."""

from importlib.metadata import PackageNotFoundError, version

try:
    __version__ = version("beambench")
except PackageNotFoundError:  # running from a source tree that is not installed
    __version__ = "0.0.0+unknown"
