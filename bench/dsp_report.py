"""The tables bench_dsp.py prints: its result (a dict, as ``--json`` writes it) as rows with
their ratios to OpenRadar and to the anchors, and as text (what each figure is: bench_dsp.py's
docstring)."""

from __future__ import annotations


# Table rows: (label, our key, OpenRadar key, anchor: the bare FFT of our backend, one thread).
ROWS = (
    ("whole chain: process + range_azimuth", "chain", None, "2d"),
    ("  range_fft", "range_fft", "range", "range"),
    ("  doppler_fft", "doppler_fft", None, "doppler"),
    ("  power", "power", None, "2d"),
    ("  CFAR (at the map's peaks)", "cfar", "cfar", "2d"),
    ("  points", "points", None, "2d"),
    ("  heatmap (range_azimuth)", "heatmap", None, "2d"),
    ("  doppler_fft + power", "doppler_power", "doppler", "doppler"),
    ("partial chain: range..cfar", "partial_chain", "partial_chain", "2d"),
)


def rows_of(result: dict) -> list[dict]:
    ours, anchors = dict(result["radarodom"]["ms"]), result["anchors"]
    backend = result["radarodom"].get("fft", "scipy")
    ours["doppler_power"] = ours["doppler_fft"] + ours["power"]
    theirs = result["openradar"]["ms"] if result["openradar"] else {}
    rows = []
    for label, key, okey, anchor in ROWS:
        akey = f"{backend}_{anchor}_w1"
        ms = ours[key]
        o = theirs.get(okey) if okey else None
        rows.append({"row": label.strip(), "key": key, "ms": ms, "openradar_ms": o,
                     "x_openradar": o / ms if o else None, "anchor": akey, "x_anchor": ms / anchors[akey]})
    return rows


def print_table(result: dict) -> None:
    m = result["machine"]
    print(f"machine: {m['cpu']}, {m['cores']} cores; Python {m['python']}, numpy {m['numpy']}, "
          f"scipy {m['scipy']}, openradar {m['openradar']}; BLAS {m['blas']}; "
          f"OPENBLAS_NUM_THREADS={m['OPENBLAS_NUM_THREADS']}")
    ro = result["radarodom"]
    print(f"frame: {tuple(result['cube_shape'])} complex64 from the {result['frame']['source']} "
          f"({result['frame']['paths']} paths); {ro['detections']} CFAR detections, {ro['points']} points; "
          f"median of {result['repeats']} runs")
    print(f"default DspConfig: FFT backend {ro['fft']}, workers=1")
    print(f"{'':<38} {'ms':>8} {'OpenRadar ms':>12} {'x OpenRadar':>11} {'x anchor':>9}  anchor")
    for r in rows_of(result):
        o = f"{r['openradar_ms']:.2f}" if r["openradar_ms"] else "-"
        xo = f"{r['x_openradar']:.2f}" if r["x_openradar"] else "-"
        label = next(lbl for lbl, key, _, _ in ROWS if key == r["key"])
        print(f"{label:<38} {r['ms']:>8.2f} {o:>12} {xo:>11} {r['x_anchor']:>9.2f}  {r['anchor']}")
    cc = result["capture_chain"]
    fast_what = f"HeatmapMaker(doppler_cells={cc['doppler_cells']})"
    modes = [("fast", f"FrameProcessor(cfg) + {fast_what}"), ("full", "FrameProcessor(cfg) + HeatmapMaker()")]
    modes += [(m, f"FrameProcessor(cfg, DspConfig(fft={m[5:]!r})) + {fast_what}") for m in cc if m.startswith("fast_")]
    for mode, what in modes:
        c = cc[mode]
        print(f"whole chain as radar-capture builds it, {mode}: {what}: "
              f"{c['median']:.2f} ms (min {c['min']:.2f}, p10 {c['p10']:.2f}, p90 {c['p90']:.2f}; "
              f"heatmap alone {c['heatmap']:.2f})")
    for key, what in (("radarodom_workers2", "DspConfig(workers=2)"), ("radarodom_scipy", "DspConfig(fft='scipy')")):
        if result.get(key):
            other = result[key]["ms"]
            print(f"whole chain with {what}: {other['chain']:.2f} ms (default: {ro['ms']['chain']:.2f} ms); stages: "
                  + ", ".join(f"{k} {v:.2f}" for k, v in other.items() if k not in ("chain", "partial_chain")))
    sp = ro["chain_spread_ms"]
    print(f"whole chain spread: min {sp['min']:.2f}, p10 {sp['p10']:.2f}, p90 {sp['p90']:.2f} ms")
    stage_sum = sum(ro["ms"][k] for k in ("range_fft", "doppler_fft", "power", "cfar", "points", "heatmap"))
    fast = cc["fast"]["median"]
    print(f"sum of stages: {stage_sum:.2f} ms; goal {result['goal_ms']:g} ms for the fast chain as radar-capture "
          f"builds it: {fast:.2f} ms, {'met' if fast <= result['goal_ms'] else 'not met'} "
          f"({fast / result['goal_ms']:.2f}x the goal; {fast / result['anchors'][ro['fft'] + '_2d_w1']:.2f}x the "
          f"one-thread 2-D anchor of {ro['fft']})")
    if result["openradar"]:
        om = result["openradar"]
        print(f"OpenRadar (clutter removal {'on' if om['clutter_removal'] else 'off'}): range {om['ms']['range']:.2f}, "
              f"doppler {om['ms']['doppler']:.2f}, cfar {om['ms']['cfar']:.2f}, partial chain "
              f"{om['ms']['partial_chain']:.2f} ms; its range cube is {om['range_cube_dtype']}; "
              f"{om['detections']} detections (its own thresholds, not comparable to ours)")
    else:
        print(f"OpenRadar: {result['openradar_unavailable']}")
    a = result["anchors"]
    print("anchors ms (lower of first/last): " + ", ".join(f"{k} {v:.2f}" for k, v in a.items()))
