"""flexopt: shape optimisation of compliant mechanisms, driven by nonlinear finite elements.

The installed package. The repository keeps its four layers at top level (``geometry/``,
``fea/``, ``optimise/``, ``pipeline/``); the wheel installs them as ``flexopt.geometry``,
``flexopt.fea``, ``flexopt.optimise`` and ``flexopt.pipeline`` (``pyproject.toml``'s
``package-dir``), and this module, the public API, from ``pipeline/api/``. See docs/api.md.
"""

from __future__ import annotations

from importlib import metadata

try:
    __version__ = metadata.version("flexopt")
except metadata.PackageNotFoundError:  # pragma: no cover - running from an unpacked tree
    __version__ = "0+unknown"

__all__ = ["__version__"]
