"""bench/paper_experiment.py's and dsp_experiment.py's command lines: a variant asked for by a name
they do not have is refused with the names they have, before anything is recorded or written."""

from __future__ import annotations

import os
import sys

import pytest

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "bench"))
import dsp_experiment  # noqa: E402
import paper_experiment  # noqa: E402


@pytest.mark.parametrize("tool, known", [(paper_experiment, "default (all of the above, keyframes)"),
                                         (dsp_experiment, "default, up to 3 azimuths a cell")])
def test_an_unknown_variant_is_refused_with_the_list(tool, known, tmp_path, capsys):
    out, data = tmp_path / "out", tmp_path / "data"
    with pytest.raises(SystemExit) as exited:
        tool.main(["--only", "default", known, "--data", str(data), "--out", str(out)])
    assert exited.value.code == 2
    err = capsys.readouterr().err
    blamed = err.split("no variant named ")[1].split("; the variants are:")[0]
    assert blamed == "'default'"  # the known name given beside it is not blamed
    assert f"  {known}" in err.splitlines()
    assert not out.exists() and not data.exists()
