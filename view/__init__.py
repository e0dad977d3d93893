"""The live view (``radar-capture --view``): the pipeline's results drawn with Rerun.

Rerun (``rerun-sdk``, the ``[view]`` extra) is imported only here, and only when a view is
opened; the rest of radarodom never needs it.
"""
