"""Range, Doppler and angle processing over the TDM-MIMO virtual array, CFAR,
point clouds and heatmaps.

Imports neither :mod:`radarodom.driver` nor zenoh: it works on cubes and a
:class:`radarodom.cfg.RadarConfig`.
"""
