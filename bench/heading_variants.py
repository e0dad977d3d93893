"""Settings that turn issue 20's heading changes off, named once for the benches that time them
(bench_estimator.py) or measure them (paper_experiment.py) against the defaults: each is a
``EstimatorConfig.with_`` argument set (docs/heading.md has the items)."""

#: Item 36 off: the yaw-rate filter's lag unbounded and given again after the keyframes (the
#: defaults before the fifth session of 2026-12-04).
LAG_GIVEN_TWICE = {"odometry": {"yaw_filter_max_lag_rad": None, "keyframe_pays_lag": False,
                                "yaw_filter_max_lag_trusted_only": False}}

#: Item 35 off: no map of wall directions.
NO_WALL_MAP = {"wall_map": {"use": False}}

#: Item 41 off: the wall map's match gates fixed, whatever the heading turned since a wall was seen.
FIXED_WALL_GATES = {"wall_map": {"gate_turn_error": False}}

#: Items 30 and 35 off: the heatmaps' registration alone, unblended, without the wall map.
HEATMAPS_ALONE = {"point_yaw": {"blend": 0.0}, **NO_WALL_MAP}

#: The four heading options of issue 20's first day off (the defaults of 2026-11-25 but for the
#: changes made since).
FOUR_OPTIONS_OFF = {"icp": {"score_support": "inside", "reject_moving_mps": None},
                    "features": {"elevation": "ignore"}, "odometry": {"rectification": "velocity"}}

#: Item 38 off: the points' map's points not weighed by the map's density around them (the
#: defaults before 2026-12-05's fourteenth session).
NO_DENSITY_WEIGHTS = {"point_yaw": {"density_weighted": False}}
