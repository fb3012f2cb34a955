"""Load what an evaluate's or a run's report files first need, in a thread, while the design
is solved (issue 27 item 4).

matplotlib (the PNG plots) takes ~0.3 s CPU to import and set up on its first use, trimesh and
manifold3d (the part's solid) more; the compiled kernels release the GIL while they solve
(``nogil=True``), so on a machine with a core free that work overlaps the solve instead of
following it. Nothing here changes a file: the same modules are imported either way.
"""

from __future__ import annotations

import logging
import threading

log = logging.getLogger(__name__)


def _load() -> None:
    try:
        # manifold3d, trimesh: the part's solid (report.html's 3D view); geometry.solid imports
        # them only where a solid is made, so that load_study does not pay them (~0.4 s CPU)
        import manifold3d  # noqa: F401
        import matplotlib.backends.backend_agg  # noqa: F401  (the plots' first import)
        import matplotlib.figure  # noqa: F401
        import trimesh  # noqa: F401
        from flexopt.pipeline.html_templates import warm_up

        warm_up()
    except Exception as exc:  # the report imports it again, and says what fails
        log.info("preloading the report failed: %s: %s", type(exc).__name__, exc)


def start() -> threading.Thread:
    """Start the loading thread (a daemon: a failed solve does not wait for it); ``join`` it
    before the first plot so that the two threads do not import the same modules at once."""
    thread = threading.Thread(target=_load, name="flexopt-report-preload", daemon=True)
    thread.start()
    return thread
