"""Opening a view: the target checked, the drawer chosen (a process of its own or a thread) and
the sink that hands it the pipeline's frames.  Rerun is imported when a view opens."""

from __future__ import annotations

import logging
from concurrent.futures import ThreadPoolExecutor
from typing import TYPE_CHECKING

from .process import ProcessDrawer
from .sink import ThreadDrawer, ViewSink
from .target import ViewTarget, check, open_scene, viewer_hint, viewer_missing

if TYPE_CHECKING:
    from ..cfg import RadarConfig
    from ..estimator.config import EstimatorConfig
    from ..mount import Mount

log = logging.getLogger(__name__)


def open_view(target: ViewTarget, *, estimator: EstimatorConfig | None = None, config: RadarConfig | None = None,
              mount: Mount | None = None, close_timeout_s: float = 30.0, process: bool | None = None) -> ViewSink:
    """A view sink drawing into *target*; its ``where`` says where to look, in one line (the
    sink's other settings: :class:`ViewSink`).  What a viewer or a browser reads (``spawn``,
    ``web``, ``connect``) is drawn in a process of its own (:mod:`.process`): a reader that lags
    or stops can hold Rerun's calls up, and there they hold up the view alone; a file is drawn in
    a thread (*process* forces either).  Raises UsageError for a target that cannot work here (no
    display, a port in use) and CaptureError for a file that cannot be written."""
    check(target)
    # Whether a viewer answers is asked while the view's process starts (both take seconds).
    with ThreadPoolExecutor(1, thread_name_prefix="viewer-probe") as pool:
        probe = pool.submit(viewer_missing, target)
        if process if process is not None else target.kind != "save":
            drawer = ProcessDrawer(target, estimator=estimator, config=config, mount=mount)
            drawer.missing = probe.result()
        else:
            scene, where = open_scene(target, estimator=estimator, config=config, mount=mount)
            drawer = ThreadDrawer(scene, where)
        missing = probe.result()
    if missing:
        log.warning("%s: the view's data waits for one (start it: rerun), and at the end the run waits up to %.0f s "
                    "for it to take the rest", missing, close_timeout_s)
    if drawer.unreachable:
        log.warning("%s; the view is not drawn: %s", drawer.unreachable, viewer_hint(target))
    return ViewSink(drawer, close_timeout_s=close_timeout_s, path=target.path if target.kind == "save" else None)
