"""Ego-velocity from Doppler, yaw from heatmap registration, and odometry.

Imports neither :mod:`radarodom.driver` nor zenoh: it takes point clouds and
heatmaps with timestamps and returns odometry.
"""
