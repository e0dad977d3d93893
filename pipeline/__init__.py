"""One frame's path, top-down: source -> raw sinks (recording) -> products -> odometry -> sinks.

    with Pipeline.from_url("sim://corridor?rate=max&duration=5", sinks=[TumSink("odom.tum")]) as pipe:
        stats = pipe.run()

:meth:`Pipeline.run` iterates the source until it ends, a limit is reached or
:meth:`Pipeline.stop` is called (a signal handler does that); for each frame it counts it and
hands it to :meth:`Pipeline.process`: the sinks that take raw frames first (a
:class:`CaptureSink` records the bytes before anything can fail on them), then the frame's point
cloud and heatmap (the source's own, or the DSP's, made only when something needs them), the
estimator fed by the frame's role (:class:`OdometryFeed`), and every other sink in order.  The
sinks are closed when the run ends, whatever ends it, the raw ones first.  Statistics, latency
and the estimator's times are kept in :class:`PipelineStats` as the run goes.

The parts are chosen once, when the pipeline is built: the products' DSP, the estimator and
its feed, which roles need a heatmap.  Command-line programs parse their arguments, build a
pipeline, and render its statistics.
"""

from __future__ import annotations

import logging
import math
import os
import time
from typing import Callable, Iterable, Sequence

from ..cfg import RadarConfig
from ..driver.sources import ROLES, Frame, Source, open_source
from ..dsp.config import DspConfig
from ..errors import CaptureError, UsageError, add_note, quoted
from ..estimator.config import EstimatorConfig
from ..estimator.odometry import OdometryState, RadarOdometry
from ..plain_numbers import is_number, is_whole_number
from ..products import Products
from .products import FrameProducts, check_features_fit
from .sinks import CaptureSink, FrameResult, HeatmapSink, OdometryJsonSink, PointsCsvSink, Sink, TumSink
from .stats import LatencyMeter, PipelineStats, RateMeter

log = logging.getLogger(__name__)

#: Stream times are kept to the nanosecond: 1000.15 - 1000.0 (0.14999...) counts as 0.15 s.
_DURATION_TOLERANCE_S = 1e-6


def _check_source(source, opener: str) -> None:
    """:class:`UsageError` unless *source* is a :class:`Source` (*opener* makes one from a URL)."""
    if isinstance(source, (str, bytes, os.PathLike)):
        raise UsageError(f"source: a Source, got the {type(source).__name__} {quoted(source)} "
                         f"({opener} opens one from a URL)")
    if not isinstance(source, Source):
        raise UsageError(f"source: a Source (open_source(url) opens one), got {type(source).__name__}")


def _check_estimator(config, name: str) -> None:
    """:class:`UsageError` unless *config* is an :class:`EstimatorConfig` or None."""
    if config is not None and not isinstance(config, EstimatorConfig):
        raise UsageError(f"{name}: an EstimatorConfig (EstimatorConfig.from_dict makes one from a dict) or "
                         f"None, got {type(config).__name__}")


def source_estimator(source: Source, config: EstimatorConfig | None = None) -> EstimatorConfig:
    """The estimator settings for *source*'s frames: *config* (default the built-in ones) with the
    preset the source calls for applied (``Source.estimator_preset``: a ``tidemo://`` source's
    points and static heatmap take ``EstimatorConfig.tidemo()``'s changes).  Settings a user chose
    for the source (radar-capture's --estimator-config) are used as they are instead."""
    _check_source(source, "open_source")
    _check_estimator(config, "config")
    config = EstimatorConfig() if config is None else config
    if source.estimator_preset is not None:
        log.info("estimator: the %r preset for this source's frames", source.estimator_preset)
    return config.preset(source.estimator_preset)


class OdometryFeed:
    """Feeds a frame's products to the estimator's stream(s) its role names: a "velocity" frame's
    point cloud, a "heatmap" frame's heatmap, or both; the new odometry state, or None for a
    velocity-only frame (the pose moves on heatmap frames)."""

    def __init__(self, odometry: RadarOdometry) -> None:
        self.odometry = odometry
        self._by_role = {"velocity": self._velocity, "heatmap": self._heatmap, "both": self._both}

    def __call__(self, frame: Frame, products: Products) -> OdometryState | None:
        return self._by_role[frame.role](frame, products)

    def _velocity(self, frame: Frame, products: Products) -> None:
        if products.points is None:
            raise CaptureError(f"frame {frame.index}: a velocity frame without a point cloud")
        self.odometry.add_points(frame.timestamp, products.points)
        return None

    def _heatmap(self, frame: Frame, products: Products) -> OdometryState:
        return self.odometry.add_heatmap(frame.timestamp, self._checked_heatmap(frame, products))

    def _both(self, frame: Frame, products: Products) -> OdometryState:
        return self.odometry.step(frame.timestamp, products.points, self._checked_heatmap(frame, products))

    @staticmethod
    def _checked_heatmap(frame: Frame, products: Products):
        if products.heatmap is None:
            raise CaptureError(f"frame {frame.index}: a {frame.role} frame without a heatmap")
        return products.heatmap


class Pipeline:
    """A source's frames through the DSP and the estimator to sinks; see the module docstring.

    *estimator*: the estimator's settings (None: no odometry); *dsp*: the DSP's; *sinks*: where
    frames and results go, in order (those that take raw frames before any processing);
    *max_frames* / *max_duration_s*: stop after that many frames / seconds of stream time (frame
    timestamps from the first frame, so a replay at ``rate=max`` covers the same span as in real
    time).
    """

    def __init__(self, source: Source, *, estimator: EstimatorConfig | None = None, dsp: DspConfig | None = None,
                 sinks: Sequence[Sink] = (), max_frames: int | None = None, max_duration_s: float | None = None,
                 owns_source: bool = False) -> None:
        self.source = source
        self.stats = PipelineStats()
        self._owns_source = owns_source
        self._closed = self._ran = False
        self.sinks: list[Sink] = []
        self._raw_sinks: list[Sink] = []
        self._result_sinks: list[Sink] = []
        try:
            given = [sinks] if _is_sink(sinks) else _sink_list(sinks)
            # Closed below if the rest fails, each once (a sink given twice is refused).
            self.sinks = list({id(s): s for s in given if _is_sink(s)}.values())
            self._raw_sinks = [s for s in self.sinks if s.takes_raw]
            self._result_sinks = [s for s in self.sinks if not s.takes_raw]
            _check_sinks(sinks, given)
            self._build(estimator, dsp, max_frames, max_duration_s)
        except BaseException as failure:
            # Nothing ran: the sinks take back what they made (an empty file would block the next
            # run), and a source opened for this pipeline is closed (a radar's ports freed).
            _close_after(failure, self.close)
            raise

    def _build(self, estimator: EstimatorConfig | None, dsp: DspConfig | None, max_frames: int | None,
               max_duration_s: float | None) -> None:
        source = self.source
        _check_source(source, "Pipeline.from_url")
        _check_estimator(estimator, "estimator")
        if dsp is not None and not isinstance(dsp, DspConfig):
            raise UsageError(f"dsp: a DspConfig (DspConfig.from_dict makes one from a dict) or None, "
                             f"got {type(dsp).__name__}")
        self.max_frames, self.max_duration_s = _checked_limits(max_frames, max_duration_s)
        self.feed = None if estimator is None else OdometryFeed(RadarOdometry(estimator))
        # Nothing to compute for (recording alone): no DSP at all.
        self.products = None
        full = any(getattr(s, "full_heatmaps", False) for s in self._result_sinks)
        if self.feed is not None or self._result_sinks:
            features = (estimator or EstimatorConfig()).features
            if self.feed is not None:  # settings that cannot run on these heatmaps fail now, not at a frame
                check_features_fit(source, features, dsp)
            # A sink that shows full maps gets them, the estimator its own kind all the same.
            self.products = FrameProducts(source.config, dsp, coupling=source.coupling, calibrated=source.calibrated,
                                          doppler_cells=None if full and self.feed is None else features.doppler_cells,
                                          full_heatmaps=full)
        # A heatmap is made when the estimator or a sink takes it; a velocity-only frame's only
        # for a sink that wants every heatmap (FrameProducts.shown_heatmap's, beside an estimator).
        wanted = self.feed is not None or any(getattr(s, "wants_heatmaps", False) for s in self._result_sinks)
        self._heatmap_for = {role: wanted for role in ROLES}
        self._heatmap_for["velocity"] = full and self.feed is None

    @classmethod
    def from_url(cls, url: str, config: RadarConfig | None = None, **kwargs) -> Pipeline:
        """A pipeline on the source *url* opens (closed with the pipeline, or at once when the
        pipeline cannot be built); *kwargs* as for the constructor."""
        source = open_source(url, config)
        try:
            return cls(source, owns_source=True, **kwargs)
        except TypeError as failure:  # a keyword the constructor does not take: __init__ never ran
            _close_after(failure, source.close)
            raise

    # ------------------------------------------------------------------ one frame
    def process(self, frame: Frame) -> FrameResult:
        """The frame, given to the sinks that take raw frames; its products and odometry, given
        to every other sink."""
        if not isinstance(frame, Frame):
            raise UsageError(f"frame: a source's Frame (radarodom.driver.sources.Frame), got {type(frame).__name__}")
        for sink in self._raw_sinks:
            sink.write_raw(frame, self.stats)
        if self.products is None:
            return FrameResult(frame, None, None, None)
        if frame.role not in ROLES:  # a Source of the user's own (a recording alone takes any)
            raise CaptureError(f"frame {frame.index}: role {frame.role!r} is not one of {', '.join(ROLES)}")
        products = self.products(frame, heatmap=self._heatmap_for[frame.role])
        state = None if self.feed is None else self.feed(frame, products)
        if state is not None:
            self.stats.state = state
            self.stats.estimator_s.append(state.compute_s)
        result = FrameResult(frame, products.points, self.products.shown_heatmap(products), state)
        for sink in self._result_sinks:
            sink.write(result, self.stats)
        self.stats.latency.add(time.monotonic() - frame.ready_monotonic)
        return result

    # ------------------------------------------------------------------ the run
    def run(self, on_frame: Callable[[FrameResult, PipelineStats], None] | None = None) -> PipelineStats:
        """Stream the source through the pipeline until it ends, a limit is reached or
        :meth:`stop`; *on_frame* is called after each frame (a status display).  The sinks are
        closed before this returns or raises."""
        if self._ran or self._closed:
            raise UsageError("a Pipeline runs once, and this one has " + ("run" if self._ran else "been closed")
                             + ": build a new one (its sinks and source are closed)")
        if on_frame is not None and not callable(on_frame):  # before a frame, not after the first
            raise UsageError(f"on_frame: a function of (FrameResult, PipelineStats) or None, got "
                             f"{type(on_frame).__name__}")
        self._ran = True
        stats = self.stats
        stats.reason = "end of source"
        try:
            self._stream(on_frame)
        except BaseException as failure:
            stats.reason = "stopped by an error"
            stats.elapsed_s = time.monotonic() - stats.started_monotonic
            _close_after(failure, self._finish)
            raise
        stats.elapsed_s = time.monotonic() - stats.started_monotonic
        self._finish()
        log.debug("run ended (%s) after %d frames", stats.reason, stats.frames)
        return stats

    def _stream(self, on_frame: Callable[[FrameResult, PipelineStats], None] | None) -> None:
        stats = self.stats
        for frame in self.source:
            if self._past_duration(frame):
                stats.reason = "duration limit"
                stats.unstreamed_lost_bytes += frame.missing_bytes - frame.cut_bytes
                break
            stats.count(frame.timestamp, frame.missing_bytes, frame.cut_bytes)
            result = self.process(frame)
            stats.frames_written += 1
            stats.rate.tick()
            if on_frame is not None:
                on_frame(result, stats)
            if self.max_frames is not None and stats.frames >= self.max_frames:
                stats.reason = "frame limit"
                break
        if self.source.stop_requested:
            stats.reason = "stopped"

    def _past_duration(self, frame: Frame) -> bool:
        first = self.stats.first_timestamp
        return (self.max_duration_s is not None and first is not None
                and frame.timestamp - first >= self.max_duration_s - _DURATION_TOLERANCE_S)

    def stop(self) -> None:
        """Stop after the current frame (safe from a signal handler)."""
        self.source.stop()

    def _finish(self) -> None:
        """Close the sinks, once: the raw ones (a recording) first, so that they are complete
        before slower outputs finish."""
        if self._closed:
            return
        self._closed = True
        # Every sink gets closed (its file flushed) even when another's close fails.
        failure: BaseException | None = None
        for sink in self._raw_sinks + self._result_sinks:
            try:
                sink.close(self.stats)
            except BaseException as exc:  # noqa: BLE001 (re-raised below, after the others)
                failure = failure or exc
        if failure is not None:
            raise failure

    def close(self) -> None:
        """Close the sinks (if :meth:`run` did not), and the source if owned."""
        try:
            self._finish()
        finally:
            if self._owns_source and isinstance(self.source, Source):
                self.source.close()

    def __enter__(self) -> Pipeline:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


def _is_sink(obj) -> bool:
    """Whether *obj* does what the pipeline asks of a sink: :class:`Sink`'s attributes and the
    methods its :attr:`~Sink.takes_raw` calls for (a sink need not subclass it: the recorders in
    driver/ do not)."""
    if isinstance(obj, type) or not hasattr(obj, "takes_raw") or not callable(getattr(obj, "close", None)):
        return False
    return callable(getattr(obj, "write_raw" if obj.takes_raw else "write", None))


def _close_after(failure: BaseException, close: Callable[[], None]) -> None:
    """*close*, after *failure*: a failure of its own is noted on *failure*, which stays the one raised."""
    try:
        close()
    except BaseException as close_failure:  # noqa: BLE001 (the first failure is the one to report)
        log.debug("closing the outputs failed too: %s", close_failure)
        add_note(failure, f"then closing the outputs failed too: {close_failure}")


def _sink_list(sinks: Sequence[Sink]) -> list:
    """*sinks* as a list, or :class:`UsageError` for anything not a list of them."""
    if isinstance(sinks, (str, bytes)) or not isinstance(sinks, Iterable):
        raise UsageError(f"sinks: a list of Sinks, got {type(sinks).__name__}")
    return list(sinks)


def _check_sinks(sinks, given: list) -> None:
    """:class:`UsageError` for one sink given alone (*sinks*) or naming the first of the list
    *given* that is no :class:`Sink`."""
    if _is_sink(sinks):
        raise UsageError(f"sinks: a list of Sinks, got one {type(sinks).__name__} (sinks=[...] gives a list)")
    for i, sink in enumerate(given):
        if isinstance(sink, type):  # its methods are there, unbound: the first frame's write failed
            raise UsageError(f"sinks[{i}]: a Sink, got the class {sink.__name__} itself; make one: "
                             f"{sink.__name__}(path)")
        if not _is_sink(sink):
            hint = " (a sink is made from a path: TumSink(path), PointsCsvSink(path), ...)" \
                if isinstance(sink, (str, os.PathLike)) else ""
            raise UsageError(f"sinks[{i}]: a Sink, got {type(sink).__name__} {quoted(sink)}{hint}")
        method = "write_raw" if sink.takes_raw else "write"
        if getattr(type(sink), method, None) is getattr(Sink, method):
            raise UsageError(f"sinks[{i}]: {type(sink).__name__} subclasses Sink but has no {method} of its own")
        first = next(j for j, other in enumerate(given) if other is sink)
        if first != i:
            raise UsageError(f"sinks[{i}] is sinks[{first}], {type(sink).__name__}: a sink given twice writes "
                             "each result twice")


def _checked_limits(max_frames, max_duration_s) -> tuple[int | None, float | None]:
    """The run's limits, or :class:`UsageError` unless each is None, a whole number >= 1 (frames) and a
    finite number > 0 (seconds)."""
    if max_frames is not None and (not is_whole_number(max_frames) or max_frames < 1):
        raise UsageError(f"max_frames: a whole number of frames >= 1 or None, got {quoted(max_frames)}")
    if max_duration_s is not None:
        if not is_number(max_duration_s) or not math.isfinite(max_duration_s) or max_duration_s <= 0:
            raise UsageError(f"max_duration_s: a number of seconds > 0 or None, got {quoted(max_duration_s)}")
        max_duration_s = float(max_duration_s)
    return None if max_frames is None else int(max_frames), max_duration_s


__all__ = ["Pipeline", "source_estimator", "PipelineStats", "OdometryFeed", "FrameResult", "Sink", "CaptureSink", "TumSink",
           "OdometryJsonSink", "PointsCsvSink", "HeatmapSink", "FrameProducts", "RateMeter", "LatencyMeter"]
