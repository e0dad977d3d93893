"""The robustness matrix's recordings kept across a change to the simulator's sources that does not
change what it records (a refactor, a comment), after checking that it does not.

    python bench/matrix_recordings.py [the matrix's cell options: --scenes, --seeds, --cfgs, ...]
        [--check-seeds 0] [--workers N] [--keep-adc] [--dry-run] [--data DIR]

bench/robustness_matrix.py keeps each cell's recording under a key that holds a fingerprint of the
simulator's sources (``sim_fingerprint``), so that a changed simulator records anew; any edit to
those sources records the whole star anew (some 45 minutes on 2 cores).  For each cell selected
(the matrix's own options) with no recording under today's key, this finds one under an earlier
key made from the same scene file and the same cfg; records anew the cells of the check seeds
(``--check-seeds``, default the selection's first seed: every scene and every axis's values once)
and compares each with its earlier recording: the ground truth and the frame times byte for byte,
the ADC samples where both still have them, and the DSP products array for array.  Only if every
checked cell is the same are the other cells' earlier recordings moved under today's keys;
otherwise the first difference is named and nothing is moved (the matrix then records those cells
anew, as it would have).  Exit status 0 when recordings were kept or none needed to be, 1 when a
difference (or no cell to check) kept them out.

    python bench/matrix_recordings.py --products [the cell options] [--check-seeds 0] [--dry-run] ...

The same across a change to the dsp package's sources (``sequences.dsp_fingerprint``): the matrix
keeps no ADC samples, so a changed DSP records every cell anew (hours).  For each cell selected whose
recording under today's key holds earlier DSP products and neither today's nor its ADC samples, the
check seeds' cells are recorded anew (in place, so that they are the matrix's recordings after) and
their products under today's DSP compared with their earlier ones array by array; cells that already
have both are compared as they are.  Only if every checked cell's are the same are the other cells'
earlier products linked as today's (a hard link: the earlier key keeps its file, for a DSP change
taken back).
"""

from __future__ import annotations

import argparse
import concurrent.futures
import glob
import json
import os
import shutil
import sys

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

import robustness_matrix as rm  # noqa: E402
import sequences  # noqa: E402
from matrix_cells import CFGS, SimCell, scene_spec  # noqa: E402

#: What a recording holds that is compared byte for byte (the ADC samples only where both have them).
_FILES = ("groundtruth.tum", "timestamps.txt", "adc_data.bin")


def earlier(cell: SimCell, data: str) -> str | None:
    """A recording of *cell* under another key than today's, made from the scene file and cfg
    today's would be (None: there is none); the newest of several."""
    today = rm._sequence_dir(cell, data)
    with open(CFGS[cell.cfg], "rb") as fh:
        cfg = fh.read()
    found = []
    for directory in glob.glob(os.path.join(data, "seq", glob.escape(cell.name) + "-*")):
        if directory == today or not os.path.isdir(directory) or not rm.recorded(directory):
            continue
        try:
            with open(rm.scene_file(directory), encoding="utf-8") as fh:
                spec = json.load(fh)
            with open(os.path.join(directory, "radar.cfg"), "rb") as fh:
                same_cfg = fh.read() == cfg
        except (OSError, ValueError):
            continue
        if same_cfg and spec == scene_spec(cell):
            found.append(directory)
    return max(found, key=os.path.getmtime) if found else None


def difference(old: str, new: str) -> str | None:
    """What differs between two recordings of a cell (None: nothing): the files of ``_FILES`` both
    have, then the DSP products of today's DSP, array by array (made where a recording still has
    its ADC samples)."""
    for name in _FILES:
        a, b = os.path.join(old, name), os.path.join(new, name)
        if name == "adc_data.bin" and not (os.path.exists(a) and os.path.exists(b)):
            continue
        with open(a, "rb") as fa, open(b, "rb") as fb:
            while True:
                ca, cb = fa.read(1 << 24), fb.read(1 << 24)
                if ca != cb:
                    return f"{name} differs"
                if not ca:
                    break
    for directory in (old, new):
        if not os.path.exists(sequences.cache_path(directory)):
            sequences.load(directory)
    return products_difference(sequences.cache_path(old), sequences.cache_path(new))


def products_difference(a_path: str, b_path: str) -> str | None:
    """What differs between two files of DSP products, array by array (None: nothing)."""
    with np.load(a_path) as a, np.load(b_path) as b:
        if sorted(a.files) != sorted(b.files):
            return f"the DSP products hold {sorted(a.files)} against {sorted(b.files)}"
        for key in a.files:
            x, y = a[key], b[key]
            # Byte for byte: the same computation gives the same NaNs, which == would call unequal.
            if x.dtype != y.dtype or x.shape != y.shape or x.tobytes() != y.tobytes():
                return f"the DSP products' {key!r} differ"
    return None


def check(cell: SimCell, old: str, data: str, keep_adc: bool) -> str | None:
    """*cell* recorded anew under today's key and compared with its *old* recording (None: the same)."""
    new = rm.record(cell, data)
    found = difference(old, new)
    if not keep_adc:
        rm.drop_adc(new)
    return found


def _adopt(old: str, new: str) -> None:
    """*old* moved to *new*, its scene file with it, and its capture.json's source naming that file."""
    os.replace(rm.scene_file(old), rm.scene_file(new))
    os.replace(old, new)
    path = os.path.join(new, "capture.json")
    with open(path, encoding="utf-8") as fh:
        meta = json.load(fh)
    if isinstance(meta.get("source"), str):
        meta["source"] = meta["source"].replace(os.path.basename(rm.scene_file(old)),
                                                os.path.basename(rm.scene_file(new)))
        with open(path + ".tmp", "w", encoding="utf-8") as fh:
            json.dump(meta, fh, indent=1)
        os.replace(path + ".tmp", path)


def _first_difference(compare, checks: list, data: str, keep_adc: bool, workers: int | None):
    """The first (cell's name, difference) that *compare* (:func:`check`, :func:`check_products`)
    finds among *checks*, (cell, earlier) pairs run on a local process pool; None: none."""
    with concurrent.futures.ProcessPoolExecutor(max_workers=workers) as pool:
        futures = {pool.submit(compare, c, old, data, keep_adc): c for c, old in checks}
        for fut in concurrent.futures.as_completed(futures):
            found = fut.result()
            if found is not None:
                return futures[fut].name, found
    return None


def keep_recordings(todo: list, data: str, *, check_seeds: list[int] | None = None, workers: int | None = None,
                    keep_adc: bool = False, dry_run: bool = False, log=lambda msg: print(msg, file=sys.stderr)) -> int:
    """The earlier recordings of *todo*'s simulated cells kept under today's keys once those of
    *check_seeds* (default the first simulated cell's seed) recorded anew, and any already recorded
    under today's key, are the same as their earlier ones; the exit status."""
    sims = [c for c in todo if isinstance(c, SimCell)]
    pairs = [(c, old, rm.recorded(rm._sequence_dir(c, data))) for c in sims if (old := earlier(c, data)) is not None]
    seeds = set(check_seeds) if check_seeds is not None else {sims[0].seed} if sims else set()
    checks = [(c, old) for c, old, recorded in pairs if recorded or c.seed in seeds]
    rest = [(c, old) for c, old, recorded in pairs if not (recorded or c.seed in seeds)]
    if not pairs:
        log(f"none of the {len(sims)} simulated cells has an earlier recording: nothing to keep")
        return 0
    if not checks:
        log(f"none of the {len(pairs)} earlier recordings is of seed {sorted(seeds)} to check: nothing kept")
        return 1
    log(f"{len(pairs)} earlier recordings; {len(checks)} compared with today's (seed {sorted(seeds)} recorded anew "
        "where it is not yet)")
    if dry_run:
        return 0
    found = _first_difference(check, checks, data, keep_adc, workers)
    if found is not None:
        log(f"{found[0]}: {found[1]} from its earlier recording: the simulator records otherwise now; no recording "
            "kept (the matrix records them anew)")
        return 1
    for c, old in checks:  # today's is the same: the earlier one is a spare copy
        shutil.rmtree(old, ignore_errors=True)
        if os.path.exists(rm.scene_file(old)):
            os.remove(rm.scene_file(old))
    for c, old in rest:
        _adopt(old, rm._sequence_dir(c, data))
    log(f"{len(checks)} cells recorded under today's key the same as before; {len(rest)} earlier recordings kept "
        "under today's keys")
    return 0


def earlier_products(directory: str, today: str) -> str | None:
    """The newest DSP products in *directory* other than those named *today* (the file name of
    today's DSP's, :func:`sequences.cache_path`), None: none."""
    found = [path for path in glob.glob(os.path.join(glob.escape(directory), "dsp-*.npz"))
             if os.path.basename(path) != today and not path.endswith(".tmp.npz")]
    return max(found, key=os.path.getmtime) if found else None


def check_products(cell: SimCell, old: str, data: str, keep_adc: bool) -> str | None:
    """*cell*'s DSP products under today's DSP (its recording made anew where it has no ADC samples,
    its *old* products set aside meanwhile) compared with *old* (None: the same)."""
    directory = rm._sequence_dir(cell, data)
    if not os.path.exists(sequences.cache_path(directory)):
        aside = directory + ".earlier-" + os.path.basename(old)
        os.replace(old, aside)  # recording anew replaces the folder
        try:
            rm.record(cell, data)
            sequences.load(directory)
            return products_difference(aside, sequences.cache_path(directory))
        finally:
            if not keep_adc:
                rm.drop_adc(directory)
            os.makedirs(directory, exist_ok=True)
            os.replace(aside, old)  # kept, for a DSP change taken back
    return products_difference(old, sequences.cache_path(directory))


def keep_products(todo: list, data: str, *, check_seeds: list[int] | None = None, workers: int | None = None,
                  keep_adc: bool = False, dry_run: bool = False, log=lambda msg: print(msg, file=sys.stderr)) -> int:
    """The earlier DSP products of *todo*'s simulated cells linked as today's once those of
    *check_seeds* (default the first simulated cell's seed), made anew, and any already made are
    the same as their earlier ones; the exit status."""
    sims = [c for c in todo if isinstance(c, SimCell)]
    # Every cell's products of today's DSP have one name (default settings, the recording's own
    # cfg), whose key hashes the DSP's sources: made once.
    today = os.path.basename(sequences.cache_path(data))
    made, needed = [], []  # (cell, its earlier products) with today's products, and without them or ADC samples
    for c in sims:
        directory = rm._sequence_dir(c, data)
        old = earlier_products(directory, today) if os.path.exists(os.path.join(directory, "capture.json")) else None
        if old is not None and os.path.exists(os.path.join(directory, today)):
            made.append((c, old))
        elif old is not None and not os.path.exists(os.path.join(directory, "adc_data.bin")):
            needed.append((c, old))
    if not needed:
        log(f"none of the {len(sims)} simulated cells' recordings needs earlier DSP products: nothing to keep")
        return 0
    seeds = set(check_seeds) if check_seeds is not None else {sims[0].seed}
    checks = made + [(c, old) for c, old in needed if c.seed in seeds]
    rest = [(c, old) for c, old in needed if c.seed not in seeds]
    if not checks:
        log(f"none of the {len(needed)} cells needing earlier DSP products is of seed {sorted(seeds)} to check, "
            "nor has any other cell today's: nothing kept")
        return 1
    log(f"{len(needed)} cells need earlier DSP products; {len(checks)} compared with today's DSP's (seed "
        f"{sorted(seeds)} recorded anew where it has no ADC samples)")
    if dry_run:
        return 0
    found = _first_difference(check_products, checks, data, keep_adc, workers)
    if found is not None:
        log(f"{found[0]}: {found[1]} from the earlier DSP's: the DSP computes otherwise now; no products kept "
            "(the matrix records the cells anew)")
        return 1
    # The key of a cell's products under the default settings depends on the DSP's sources alone, so
    # the checked cells' earlier file names are those of the DSP checked; another name is products
    # of other settings (bench/dsp_experiment.py's) or of another DSP, and is left alone.
    checked = {os.path.basename(old) for _, old in checks}
    linked = 0
    for c, old in rest:
        directory = rm._sequence_dir(c, data)
        same = [name for name in checked if os.path.exists(os.path.join(directory, name))]
        if not same:
            continue
        old = max((os.path.join(directory, name) for name in same), key=os.path.getmtime)
        try:
            os.link(old, os.path.join(directory, today))
        except OSError:  # a file system without hard links
            shutil.copyfile(old, os.path.join(directory, today))
        linked += 1
    log(f"{len(checks)} cells' DSP products the same under today's DSP; {linked} cells' earlier products linked "
        f"as today's" + (f" ({len(rest) - linked} hold none of the checked DSP's)" if linked < len(rest) else ""))
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    rm.add_cell_arguments(parser)
    parser.add_argument("--check-seeds", nargs="+", type=int, metavar="SEED",
                        help="the seeds whose cells are recorded anew and compared (default: the first of --seeds)")
    parser.add_argument("--workers", type=int, default=None, help="local processes (default: the CPU count)")
    parser.add_argument("--keep-adc", action="store_true", help="keep the checked cells' ADC samples")
    parser.add_argument("--dry-run", action="store_true", help="say what would be recorded and kept, and stop")
    parser.add_argument("--products", action="store_true",
                        help="keep the DSP products across a change to the dsp package (not the recordings "
                             "across one to the simulator)")
    args = parser.parse_args(argv)
    todo = rm.selected_cells(args)
    if not todo:
        parser.error("no cells selected")
    keep = keep_products if args.products else keep_recordings
    return keep(todo, args.data, check_seeds=args.check_seeds, workers=args.workers, keep_adc=args.keep_adc,
                dry_run=args.dry_run)


if __name__ == "__main__":
    sys.exit(main())
