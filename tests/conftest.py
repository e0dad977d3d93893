"""Shared fixtures.  No test needs hardware; tests that read the reference
material in ``../shared/reference`` skip with a reason when it is absent (a
user's clone has no ``../shared``)."""

from __future__ import annotations

import logging
import os
import pathlib
import shutil
import sys

# One OpenBLAS thread in the test workers and the programs they start, as radar-capture and
# radar-calibrate set for themselves: two workers on two cores each with a thread per core made
# the simulator's matrix products spin against each other (twice the CPU time of a test file that
# simulates; docs/library.md, "The tests"). Before numpy loads; an explicit setting wins, and the
# tests about the thread count set theirs.
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

import numpy as np  # noqa: E402  (after the BLAS setting)
import pytest
from hypothesis import settings

# Property tests draw the same examples on every run (CI must not go red by chance);
# no example database is written into the checkout.
settings.register_profile("radarodom", derandomize=True, database=None, deadline=None)
settings.load_profile("radarodom")

from radarodom.cfg import RadarConfig
from radarodom.driver.recordings.capture_dir import CaptureWriter


def pytest_configure(config):
    # A shell without job control starts a background command (`pytest &`, a CI runner's
    # script) with SIGINT ignored, and a child inherits that: Python then installs no Ctrl-C
    # handler, and the tests that stop a program with SIGINT waited for it in vain. The suite's
    # own process takes Ctrl-C as Python's default does, and so does every program it starts.
    import signal

    if signal.getsignal(signal.SIGINT) == signal.SIG_IGN:
        signal.signal(signal.SIGINT, signal.default_int_handler)
    # The solved CFAR scales the programs keep (radarodom.dsp.kept_scales) go to a directory of
    # the run's, not the user's cache: made here before xdist starts its workers, which inherit it
    # with the programs they start.
    if "RADARODOM_CACHE_DIR" not in os.environ:
        import tempfile

        config._radarodom_cache = os.environ["RADARODOM_CACHE_DIR"] = tempfile.mkdtemp(prefix="radarodom-test-cache-")


def pytest_unconfigure(config):
    made = getattr(config, "_radarodom_cache", None)
    if made:
        shutil.rmtree(made, ignore_errors=True)
        os.environ.pop("RADARODOM_CACHE_DIR", None)

REPO = pathlib.Path(__file__).resolve().parent.parent
SHARED = pathlib.Path(os.environ.get("RADARODOM_SHARED", REPO.parent / "shared")) / "reference"

#: A small but complete raw-capture cfg (3 TX, 4 RX, 4 loops, 16 samples): 3072-byte frames.
SMALL_CFG = """\
% small test profile
sensorStop
flushCfg
dfeDataOutputMode 1
channelCfg 15 7 0
adcCfg 2 1
adcbufCfg -1 0 1 1 1
profileCfg 0 77 100 6 40 0 0 96 1 16 8000 0 0 30
chirpCfg 0 0 0 0 0 0 0 1
chirpCfg 1 1 0 0 0 0 0 4
chirpCfg 2 2 0 0 0 0 0 2
frameCfg 0 2 4 0 50 1 0
lowPower 0 0
lvdsStreamCfg -1 0 1 0
sensorStart
"""


@pytest.fixture
def shared_reference() -> pathlib.Path:
    """``../shared/reference``, or skip."""
    if not SHARED.is_dir():
        pytest.skip(f"reference material not found at {SHARED} (only CI and developers have it)")
    return SHARED


@pytest.fixture
def small_cfg() -> RadarConfig:
    return RadarConfig.from_text(SMALL_CFG, "small.cfg")


@pytest.fixture
def shipped_cfg() -> RadarConfig:
    return RadarConfig.from_file(REPO / "configs" / "awr1843_raw.cfg")


def random_frames(cfg: RadarConfig, n: int, seed: int = 0) -> list[bytes]:
    """*n* frames of random int16 samples, as raw bytes."""
    rng = np.random.default_rng(seed)
    return [rng.integers(-3000, 3000, cfg.frame_bytes // 2, dtype="<i2").tobytes() for _ in range(n)]


def make_capture(directory, cfg: RadarConfig, n: int = 10, *, t0: float = 1000.0,
                 incomplete: dict[int, int] | None = None, poses: bool = False, seed: int = 0):
    """Write a capture directory of *n* random frames at the cfg's frame period.

    Returns the list of frame bytes written.
    """
    frames = random_frames(cfg, n, seed)
    incomplete = incomplete or {}
    with CaptureWriter(directory, cfg, source="test") as writer:
        for i, raw in enumerate(frames):
            pose = (0.1 * i, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0) if poses else None
            writer.write(raw, t0 + i * cfg.frame_period_s, incomplete.get(i, 0), pose)
    return frames


def run_together(*calls: dict) -> list:
    """``subprocess.run(**call)`` for every call at the same time, each on a thread of its own:
    independent programs (none reads what another writes) then take about the time of the
    longest on two cores instead of the sum.  The CompletedProcesses in the calls' order; an
    exception of one (its timeout, say) is raised once every run has ended."""
    import subprocess
    from concurrent.futures import ThreadPoolExecutor

    with ThreadPoolExecutor(len(calls)) as pool:
        futures = [pool.submit(subprocess.run, **call) for call in calls]
    return [future.result() for future in futures]


def console_command(name: str) -> list[str]:
    """The installed console script *name*, or ``python -m`` of its module."""
    path = os.pathsep.join([os.path.dirname(sys.executable), os.environ.get("PATH", "")])
    found = shutil.which(name, path=path)
    if found:
        return [found]
    return [sys.executable, "-m", "radarodom.tools." + name.replace("-", "_")]


@pytest.fixture
def run_main(capsys):
    """``run_main(name, *args)``: program *name*'s ``main()`` run in this process, its exit code
    and what it printed as a ``subprocess.CompletedProcess``.  For the runs whose subject is
    the program's answer (a refusal, a summary), not the process (signals, a terminal, the
    environment at start-up): a subprocess of each program pays its imports again, about half
    a second (tests that keep one check the console script itself)."""
    import importlib
    import subprocess
    import warnings

    def show(message, category, filename, lineno, file=None, line=None):
        sys.stderr.write(warnings.formatwarning(message, category, filename, lineno, line))

    def run(name: str, *args) -> subprocess.CompletedProcess:
        program = importlib.import_module("radarodom.tools." + name.replace("-", "_"))
        argv = [str(a) for a in args]
        capsys.readouterr()  # what came before is not this run's
        # Python's warnings (numpy's RuntimeWarning) on the program's stderr under Python's own
        # filters, as a subprocess prints them: pytest's would collect them unseen.
        with warnings.catch_warnings():
            warnings.resetwarnings()
            for category in (DeprecationWarning, PendingDeprecationWarning, ImportWarning, ResourceWarning):
                warnings.simplefilter("ignore", category)
            warnings.showwarning = show
            code = program.main(argv)
        out, err = capsys.readouterr()
        return subprocess.CompletedProcess([name, *argv], code, out, err)
    return run


@pytest.fixture
def capture_main(run_main):
    """``capture_main(*args)``: radar-capture's run in this process (:func:`run_main`), publishing
    on a free port of its own unless it says where (:func:`private_zenoh`), as the subprocess runs
    of the CLI tests do."""
    return lambda *args: run_main("radar-capture", *private_zenoh(args))


@pytest.fixture
def default_endpoint(monkeypatch) -> str:
    """The Zenoh publisher's default endpoint moved to a free loopback port for the test, so
    that it meets nothing that runs on the real one (tcp/127.0.0.1:7448) on this machine."""
    from radarodom import zenoh_session

    endpoint = free_endpoint()
    monkeypatch.setattr(zenoh_session, "DEFAULT_ENDPOINT", endpoint)
    return endpoint


def free_endpoint() -> str:
    """A tcp/127.0.0.1 Zenoh endpoint on a port free right now."""
    import socket

    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return f"tcp/127.0.0.1:{sock.getsockname()[1]}"


def private_zenoh(argv) -> list[str]:
    """*argv* of a radar-capture run, made to publish on a free loopback port of its own unless
    it says where (``--listen``/``--connect``/``--zenoh-config``) or does not publish: a test
    never touches the user's default 7448 (a radar-capture the user runs holds it)."""
    argv = [str(a) for a in argv]
    if any(a in argv for a in ("--no-publish", "--listen", "--connect", "--zenoh-config")):
        return argv
    return [*argv, "--listen", free_endpoint()]


#: 3 s of the simulated corridor (1 s standing still, then driving straight ahead and speeding up
#: to 1.2 m/s): 30 frames at the shipped cfg's 10 Hz.
#: Fast fidelity (as the robustness matrix records): what its users compare is the run with itself
#: (replayed, converted, evaluated), not with the exact simulator.
CORRIDOR_URL = "sim://corridor?rate=max&fidelity=fast&duration=3"


@pytest.fixture(scope="session")
def corridor_run(tmp_path_factory):
    """radar-capture streaming :data:`CORRIDOR_URL` (publishing on a free loopback port of its
    own), recording it (``--record``) and writing its odometry (``--odom-out``; its messages,
    ``--odom-json``), once for the session: the same run was made by test_cli_odometry,
    test_eval_plots, test_cli_publish and test_coloradar_source each.  Namespace of base (the
    run's folder), rec, tum, odom (the messages' file), proc (the
    CompletedProcess) and seconds.  The recording and the trajectory are read, never changed:
    a test that edits the recording works on a copy (``shutil.copytree``)."""
    import subprocess
    import time
    from types import SimpleNamespace

    base = tmp_path_factory.mktemp("corridor_run")
    rec, tum, odom = base / "rec", base / "live.tum", base / "live.jsonl"
    start = time.monotonic()
    proc = subprocess.run(console_command("radar-capture") + private_zenoh(["--source", CORRIDOR_URL, "--record", rec,
                                                                            "--odom-out", tum, "--odom-json", odom]),
                          stdin=subprocess.DEVNULL, capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    return SimpleNamespace(base=base, rec=rec, tum=tum, odom=odom, proc=proc, seconds=time.monotonic() - start)


@pytest.fixture
def warnings_log(caplog):
    """caplog at WARNING for radarodom, whatever level an earlier CLI run left set."""
    caplog.set_level(logging.WARNING, logger="radarodom")
    return caplog


def warning_messages(caplog) -> list[str]:
    return [r.getMessage() for r in caplog.records if r.levelno >= logging.WARNING]


@pytest.fixture(autouse=True)
def _restore_radarodom_logger():
    """main() in-process attaches a stderr handler to the 'radarodom' logger and sets
    its level; put both back so other tests see the logger as they left it."""
    logger = logging.getLogger("radarodom")
    handlers, level = list(logger.handlers), logger.level
    yield
    logger.handlers[:] = handlers
    logger.setLevel(level)


# The live tests' sources (tests/test_live_*.py).
@pytest.fixture
def small_capture(request, tmp_path, small_cfg):
    """(directory, frames) of a SMALL_CFG capture of the test module's N_SRC frames (5 when unset)."""
    directory = tmp_path / "src"
    return str(directory), make_capture(directory, small_cfg, getattr(request.module, "N_SRC", 5), seed=3)


@pytest.fixture
def loss_cfg() -> RadarConfig:
    from live_helpers import LOSS_CFG

    return RadarConfig.from_text(LOSS_CFG, "loss.cfg")


@pytest.fixture
def loss_capture(tmp_path, loss_cfg):
    """(directory, frames) of a 7-frame LOSS_CFG capture (12288 bytes every 10 ms)."""
    directory = tmp_path / "src_loss"
    return str(directory), make_capture(directory, loss_cfg, 7, seed=1)
