"""Test the source tree: put the repository root first on ``sys.path``.

Plain ``pytest`` does not put the working directory on ``sys.path``, so without this a checkout
that was never installed cannot import its packages (``tests/pipeline``, which has no
``__init__.py``, could even be picked up as a namespace package called ``pipeline``), and one that
was installed with ``pip install .`` would test the installed copy, stale after every edit. The
installed console script is still exercised by tests/pipeline/test_cli_evaluate.py when present.
"""

from __future__ import annotations

import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

if sys.path[:1] != [str(ROOT)]:
    sys.path.insert(0, str(ROOT))
