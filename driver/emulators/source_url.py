"""The URL an emulated board opens its frames' source with."""

from __future__ import annotations

from ...errors import UsageError
from ..sources import live_scheme


def emulated_source_url(url: str, *, replaced: dict[str, str] | None = None,
                        defaults: dict[str, str] | None = None) -> str:
    """*url* with the options *replaced* set whatever it says and *defaults* where it says
    nothing (the URL's own options kept as written); a simulator's ``fidelity`` is ``fast``
    unless it says: the board streams in real time, which ``fast`` keeps up with on two cores,
    and opens its source with ``rate=max`` (the board paces), at which the simulator would
    otherwise take its slow ``exact`` fidelity.  A live radar's URL is refused (UsageError).  Open it
    with ``open_source(..., shown_url=url)``: its messages then name the URL the user gave."""
    scheme = live_scheme(url)
    if scheme:
        raise UsageError(f"{url}: a live radar ({scheme}://) cannot be emulated; give a recording (--capture "
                         f"DIR) or a sim://, replay:// or coloradar:// source")
    replaced, defaults = dict(replaced or {}), dict(defaults or {})
    if url.startswith("sim:"):
        defaults.setdefault("fidelity", "fast")
    base, _, query = url.partition("?")
    items = [q for q in query.split("&") if q and q.partition("=")[0] not in replaced]
    given = {q.partition("=")[0] for q in items}
    items += [f"{k}={v}" for k, v in defaults.items() if k not in given and k not in replaced]
    items += [f"{k}={v}" for k, v in replaced.items()]
    return base + "?" + "&".join(items) if items else base


def no_raw_frames_message(url: str) -> str:
    """What an emulated board says of a source *url* whose frames carry no raw ADC samples (a
    recording of the demo's UART stream; a ColoRadar run played from its point clouds and
    heatmaps): it streams raw frames, as the radar's ADCs give them."""
    if url.startswith("coloradar:"):
        return (f"{url}: its frames carry no raw ADC samples (a ColoRadar run plays its point clouds and "
                f"heatmaps unless told otherwise), and an emulated board streams raw frames: add "
                f"velocity=single_chip_adc&heatmap=single_chip_adc to the URL (the run's single-chip ADC "
                f"frames), or play it with radar-capture --source {url}")
    return (f"{url}: its frames carry no raw ADC samples (a recording of the demo's UART stream holds its "
            f"packets only), and an emulated board streams raw frames; play it with radar-capture --source {url}")
