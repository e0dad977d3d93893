"""The live view (``radar-capture --view``): the pipeline's results drawn with Rerun.

    sink = open_view(ViewTarget("save", path="run.rrd"), estimator=EstimatorConfig())
    Pipeline(source, estimator=EstimatorConfig(), sinks=[sink]).run()
    print(sink.where, sink.summary)

:func:`open_view` (:mod:`.opener`) opens the target (a viewer spawned here, the web viewer
served, a viewer elsewhere, an .rrd file) in a process of its own (:mod:`.process`) and returns
a :class:`ViewSink` (:mod:`.sink`), which hands each frame's :mod:`.frames` over; :mod:`.scene`
says what is drawn and where, :mod:`.target` where it goes.  Rerun (``rerun-sdk``, the ``[view]`` extra) is imported only when a view
opens: the rest of radarodom never needs it.
"""

from .frames import Track
from .opener import open_view
from .sink import ThreadDrawer, ViewSink
from .target import ViewTarget, open_scene

__all__ = ["ViewSink", "ViewTarget", "Track", "ThreadDrawer", "open_view", "open_scene"]
